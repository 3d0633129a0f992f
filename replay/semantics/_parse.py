"""The action grammar (PROTOCOL §2): raw model text -> a typed action or a typed failure.

Grammar (case-insensitive names, whitespace anywhere between tokens)::

    response   := [ "Thinking:" text ] entry
    entry      := label call trailer          -- exactly one entry per response
    label      := line-start decoration* "Action" decoration* ":"   (decoration: * _ # > ` - space)
    call       := fence? bold? NAME "(" [ arg ( "," arg )* [","] ] ")" bold? fence? ["." | ";"]
    arg        := ("coord" | "coords" | "coordinate") "=" list
                | ("params" | "param" | "parameters") "=" ( list | item )
    list       := "[" [ item ( "," item )* [","] ] "]"  |  "(" ... ")"
    item       := NUMBER | QUOTED | WORD | "*"

A response without a line-start label may still carry one mid-line (`Thinking: ... Action:
Press(...)`); it is then found anywhere. Text after the call is ignored unless it holds
another call of a known action (`multiple_actions`). Parsing never raises.
"""

from __future__ import annotations

import re
from math import isfinite

import msgspec

from ._vocab import ACTION_NAMES, DISPLAY_NAMES, TIMED_WAIT, normalize_param

_LABEL_LINE = re.compile(r"^[ \t>*_#`\-]*action[ \t*_`]*:", re.IGNORECASE | re.MULTILINE)
_LABEL_ANY = re.compile(r"\baction[ \t*_`]*:", re.IGNORECASE)
_THINKING = re.compile(r"^[ \t>*_#`\-]*thinking[ \t*_`]*:", re.IGNORECASE | re.MULTILINE)
_LEAD = re.compile(r"[\s*_]*(?:```[A-Za-z0-9_+-]*[ \t]*\n|```)?[\s*_`]*")
_NAME = re.compile(r"([A-Za-z_][A-Za-z0-9_]*)\s*\(")
# A second call in the same entry; no space before "(" so prose like "press (gently)" passes.
_KNOWN_CALL = re.compile(
    r"\b(?:press|rotate|push|pull|grasp|switch_view|timed_wait)\(", re.IGNORECASE
)
_NUMBER = re.compile(r"[-+]?(?:\d+(?:\.\d*)?|\.\d+)(?:[eE][-+]?\d+)?")
_WORD = re.compile(r"[A-Za-z0-9_*.+\-]+")
_KEY = re.compile(r"([A-Za-z_]+)\s*=\s*")
_COORD_KEYS = frozenset({"coord", "coords", "coordinate", "coordinates"})
_PARAM_KEYS = frozenset({"params", "param", "parameters", "parameter"})
_KNOWN = {name: name for name in ACTION_NAMES}
# Fast path for the common, canonical shape `Name(coord=[x, y], params=[a, b])`; anything
# else (quotes, fences, odd order, errors) goes through the full grammar below, and a test
# checks that both paths agree wherever the fast one applies.
_NUM = r"([-+]?\d+(?:\.\d+)?)"
_FAST_COORD = r"coord\s*=\s*\[\s*" + _NUM + r"\s*,\s*" + _NUM + r"\s*\]"
_FAST_PARAMS = r"params\s*=\s*\[([A-Za-z0-9_*.+\-'\", \t]*)\]"
_FAST = re.compile(
    r"\s*(?:```[A-Za-z0-9_+-]*[ \t]*\n|`|\*\*)?[ \t]*(([A-Za-z_]+)\(\s*(?:(?:"
    + _FAST_COORD
    + r"(?:\s*,\s*"
    + _FAST_PARAMS
    + r")?|"
    + _FAST_PARAMS
    + r")\s*(?:,\s*)?)?\))[ \t]*(?:`|\*\*|\n```)?[ \t]*\.?\s*\Z"
)
_FAST_ITEM = re.compile(r"(['\"]?)([A-Za-z0-9_*.+\-]+)\1")


class Action(msgspec.Struct, frozen=True):
    """A well-formed action: `type` is a lowercase name from PROTOCOL §2."""

    type: str
    coord: tuple[float, float] | None = None
    params: tuple[str, ...] = ()

    def to_text(self) -> str:
        """Canonical call text, e.g. `Press(coord=[500, 300], params=[0])`."""
        parts = []
        if self.coord is not None:
            parts.append(f"coord=[{_num(self.coord[0])}, {_num(self.coord[1])}]")
        if self.params or self.type != TIMED_WAIT:
            parts.append("params=[" + ", ".join(self.params) + "]")
        return f"{DISPLAY_NAMES.get(self.type, self.type)}({', '.join(parts)})"


class ParsedAction(msgspec.Struct, frozen=True):
    """Result of parsing one response: `action` when `ok`, else a `detail` code."""

    ok: bool
    action: Action | None
    detail: str | None  # one of PARSE_DETAILS when not ok
    action_text: str  # the text of the Action entry (or the whole text if none)
    thinking: str  # the Thinking part, stripped ('' when absent)


def _num(v: float) -> str:
    return str(int(v)) if v == int(v) else repr(v)


class _Malformed(Exception):
    pass


def parse_action(text: str) -> ParsedAction:
    """Parse a model response (PROTOCOL §2). Never raises."""
    if not isinstance(text, str):
        return ParsedAction(False, None, "malformed", "", "")
    labels = _find_labels(text)
    thinking = _thinking(text, labels[0][0] if labels else len(text))
    if not labels:
        return ParsedAction(False, None, "no_action", "", thinking)
    if len(labels) > 1:
        entry = text[labels[0][1] : labels[1][0]].strip()
        return ParsedAction(False, None, "multiple_actions", entry, thinking)
    return _parse_entry(text[labels[0][1] :], thinking)


_LINE_DECOR = frozenset(" \t>*_#`-")
_LABEL_DECOR = frozenset(" \t*_`")


def _find_labels(text: str) -> list[tuple[int, int]]:
    """(start, end) of the `Action:` labels: the line-start ones, or if none, any.

    Equivalent to `_LABEL_LINE` / `_LABEL_ANY` (a test checks it) but built on `str.find`,
    which is several times faster on long Thinking texts; non-ASCII text whose lowercase
    form changes length uses the regexes.
    """
    low = text.lower()
    if len(low) != len(text):
        found = list(_LABEL_LINE.finditer(text)) or list(_LABEL_ANY.finditer(text))
        return [(m.start(), m.end()) for m in found]
    line: list[tuple[int, int]] = []
    anywhere: list[tuple[int, int]] = []
    n = len(text)
    # The line of each label and where its decoration ends are found going forward, each
    # character looked at once: however many labels a line holds, the time stays linear.
    start_of_line = searched = 0
    decor_end = -1  # the first character of that line that is not decoration (-1: not yet)
    pos = low.find("action")
    while pos >= 0:
        j = pos + 6
        while j < n and text[j] in _LABEL_DECOR:
            j += 1
        if j < n and text[j] == ":":
            newline = text.rfind("\n", searched, pos)
            searched = pos
            if newline >= 0:
                start_of_line, decor_end = newline + 1, -1
            if decor_end < 0:
                decor_end = start_of_line
                while decor_end < n and text[decor_end] in _LINE_DECOR:
                    decor_end += 1
            if decor_end >= pos:  # nothing but decoration before it on its line
                line.append((start_of_line, j + 1))
            elif pos == 0 or not (text[pos - 1].isalnum() or text[pos - 1] == "_"):
                anywhere.append((pos, j + 1))
        pos = low.find("action", pos + 1)
    return line or anywhere


def _thinking(text: str, end: int) -> str:
    head = text[:end]
    m = _THINKING.search(head)
    return head[m.end() :].strip() if m else head.strip()


def _parse_entry(entry: str, thinking: str) -> ParsedAction:
    fast = _FAST.match(entry)
    if fast is None:
        return _parse_entry_full(entry, thinking)
    call_text, name, x, y, params_a, params_b = fast.groups()
    kind = _KNOWN.get(name.lower())
    if kind is None:
        return _parse_entry_full(entry, thinking)
    params = fast_params(params_a if params_a is not None else params_b)
    if params is None:
        return _parse_entry_full(entry, thinking)
    coord = (float(x), float(y)) if x is not None else None
    if coord is not None and not (isfinite(coord[0]) and isfinite(coord[1])):
        return _parse_entry_full(entry, thinking)  # which calls it malformed
    return ParsedAction(True, Action(kind, coord, params), None, call_text, thinking)


def fast_params(raw: str | None) -> tuple[str, ...] | None:
    """The params of a fast-path match (the text inside `params=[...]`, or None when absent),
    normalised; None when an item is not a plain word or a quoted one (the full grammar
    decides then)."""
    if not raw or raw.isspace():
        return ()
    items = [p.strip() for p in raw.split(",")]
    if len(items) > 1 and not items[-1]:
        items.pop()  # one trailing comma
    values = []
    for item in items:
        m = _FAST_ITEM.fullmatch(item)
        if m is None:
            return None
        values.append(normalize_param(m.group(2)))
    return tuple(values)


def _parse_entry_full(entry: str, thinking: str) -> ParsedAction:
    lead = _LEAD.match(entry)
    pos = lead.end() if lead else 0
    shown = entry.strip()
    m = _NAME.match(entry, pos)
    if m is None:
        return ParsedAction(False, None, "malformed", shown, thinking)
    name = m.group(1)
    close = _matching_paren(entry, m.end() - 1)
    if close < 0:
        known = name.lower() in _KNOWN
        return ParsedAction(
            False, None, "malformed" if known else "unknown_action", shown, thinking
        )
    call_text = entry[pos : close + 1]
    trailer = entry[close + 1 :]
    if _KNOWN_CALL.search(trailer):
        return ParsedAction(False, None, "multiple_actions", shown, thinking)
    kind = _KNOWN.get(name.lower())
    if kind is None:
        return ParsedAction(False, None, "unknown_action", call_text, thinking)
    try:
        coord, params = _parse_args(entry[m.end() : close])
    except _Malformed:
        return ParsedAction(False, None, "malformed", call_text, thinking)
    return ParsedAction(True, Action(kind, coord, params), None, call_text, thinking)


def _matching_paren(text: str, open_at: int) -> int:
    depth = 0
    quote = ""
    for i in range(open_at, len(text)):
        ch = text[i]
        if quote:
            if ch == quote:
                quote = ""
            continue
        if ch in "'\"":
            quote = ch
        elif ch == "(":
            depth += 1
        elif ch == ")":
            depth -= 1
            if depth == 0:
                return i
    return -1


def _parse_args(args: str) -> tuple[tuple[float, float] | None, tuple[str, ...]]:
    coord: tuple[float, float] | None = None
    params: tuple[str, ...] = ()
    seen: set[str] = set()
    pos = _skip_ws(args, 0)
    while pos < len(args):
        km = _KEY.match(args, pos)
        if km is None:
            raise _Malformed
        key = km.group(1).lower()
        if key in _COORD_KEYS:
            slot = "coord"
        elif key in _PARAM_KEYS:
            slot = "params"
        else:
            raise _Malformed
        if slot in seen:
            raise _Malformed
        seen.add(slot)
        pos = km.end()
        if pos < len(args) and args[pos] in "[(":
            items, pos = _parse_list(args, pos)
        elif slot == "params":
            item, pos = _parse_item(args, pos)
            items = [item]
        else:
            raise _Malformed
        if slot == "coord":
            coord = _to_coord(items)
        else:
            params = tuple(normalize_param(v) for v in items)
        pos = _skip_ws(args, pos)
        if pos < len(args):
            if args[pos] != ",":
                raise _Malformed
            pos = _skip_ws(args, pos + 1)
    return coord, params


def _skip_ws(text: str, pos: int) -> int:
    while pos < len(text) and text[pos].isspace():
        pos += 1
    return pos


def _parse_list(text: str, pos: int) -> tuple[list[str], int]:
    closing = "]" if text[pos] == "[" else ")"
    pos = _skip_ws(text, pos + 1)
    items: list[str] = []
    if pos < len(text) and text[pos] == closing:
        return items, pos + 1
    while True:
        item, pos = _parse_item(text, pos)
        items.append(item)
        pos = _skip_ws(text, pos)
        if pos >= len(text):
            raise _Malformed
        if text[pos] == closing:
            return items, pos + 1
        if text[pos] != ",":
            raise _Malformed
        pos = _skip_ws(text, pos + 1)
        if pos < len(text) and text[pos] == closing:  # trailing comma
            return items, pos + 1


def _parse_item(text: str, pos: int) -> tuple[str, int]:
    pos = _skip_ws(text, pos)
    if pos >= len(text):
        raise _Malformed
    ch = text[pos]
    if ch in "'\"":
        end = text.find(ch, pos + 1)
        if end < 0:
            raise _Malformed
        return text[pos + 1 : end], end + 1
    m = _WORD.match(text, pos)
    if m is None:
        raise _Malformed
    return m.group(0), m.end()


def _to_coord(items: list[str]) -> tuple[float, float]:
    if len(items) != 2:
        raise _Malformed
    values = []
    for item in items:
        s = item.strip()
        if not _NUMBER.fullmatch(s):
            raise _Malformed
        value = float(s)
        if not isfinite(value):  # `1e999`, or hundreds of digits: not a coordinate
            raise _Malformed
        values.append(value)
    return values[0], values[1]


def action_from_record(type_: str, coord: list[float] | None, params: list) -> ParsedAction:
    """A structured `action` of a log step (PROTOCOL §1.4), checked like parsed text."""
    text = (
        f"{type_}(coord={coord}, params={params})"
        if coord is not None
        else f"{type_}(params={params})"
    )
    kind = _KNOWN.get(str(type_).strip().lower())
    if kind is None:
        return ParsedAction(False, None, "unknown_action", text, "")
    point: tuple[float, float] | None = None
    if coord is not None:
        if len(coord) != 2 or not all(isfinite(v) for v in coord):
            return ParsedAction(False, None, "malformed", text, "")
        point = (float(coord[0]), float(coord[1]))
    action = Action(kind, point, tuple(normalize_param(p) for p in params))
    return ParsedAction(True, action, None, action.to_text(), "")
