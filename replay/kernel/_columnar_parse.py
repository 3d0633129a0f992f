"""Parsing the steps of a batch at once (PROTOCOL §2), for the columnar replay.

Three tiers, each equal to `parse_log_step` on what it takes (`tests/replay/test_columnar.py`
checks it on generated texts):

1. polars (Rust regex), for the whole batch in a few passes: ASCII texts that start with
   `Thinking:` and contain `action` (any case) exactly once, as the line-start label
   `\\nAction:` or `\\n**Action:`. `_find_labels` then returns that one label and
   `_thinking` strips the text between `Thinking:` and it. The entry after the label is
   matched with `_FAST`'s own pattern, its `\\s` and `\\d` spelled as the ASCII classes
   Python uses on ASCII text (`str.isspace`, `[0-9]`): Rust's leftmost-first semantics
   picks the same groups as Python's backtracking (the plainest entries first with
   `SIMPLE_CALL`, a subset of `_FAST` with the same groups, several times faster). The
   name must be a known action and the params pass `_parse.fast_params` (in Python, once
   per distinct call);
2. Python, the entry only (`_known_labels`): texts starting with `Thinking:` whose labels
   are easy to find with `str.find` (one as above, none, or two `\\nAction:`), non-ASCII
   ones included, but not U+0130 (the one character whose lowercase is longer, which sends
   `_find_labels` to its regexes): the entry goes to `_parse._parse_entry`;
3. `parse_log_step` for everything else (other shapes, structured `action` records, steps
   without output).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import polars as pl
import pyarrow as pa
import pyarrow.compute as pc

from ..semantics import _parse
from ..semantics._episode import parse_log_step
from ..semantics._parse import _FAST, _KNOWN, ParsedAction, fast_params
from ..semantics._records import LogStep
from ._columnar_tables import ActionVocab

_WS_CHARS = " \t\n\r\x0b\x0c\x1c\x1d\x1e\x1f"
"""What Python's `str.isspace()` (so `str.strip()` and `re`'s `\\s`) means on ASCII."""
_WS = r"[ \t\n\r\x0b\x0c\x1c-\x1f]"


def ascii_pattern(pattern: str) -> str:
    """A Python `re` pattern meant for ASCII text, spelled for the Rust regex engine."""
    for esc in (r"\w", r"\W", r"\b", r"\B", r"\S", r"\D", r"\A", "(?i", "(?m", "(?s"):
        if esc in pattern:
            raise ValueError(f"{esc} has no checked ASCII translation")
    return pattern.replace(r"\s", _WS).replace(r"\d", "[0-9]").replace(r"\Z", r"\z")


FAST_CALL = "^" + ascii_pattern(_FAST.pattern)
"""`_FAST.match(entry)` for ASCII entries."""
_PLAIN_NUMBER = r"(-?[0-9]+)"
_PLAIN_PARAMS = r"params=\[([A-Za-z0-9_*.+\-, ]*)\]"
SIMPLE_CALL = (
    r"^ (([A-Za-z_]+)\((?:coord=\[" + _PLAIN_NUMBER + ", " + _PLAIN_NUMBER + r"\]"
    r"(?:, " + _PLAIN_PARAMS + ")?|" + _PLAIN_PARAMS + r")?\))\z"
)
"""The plainest entries, ` Name(coord=[x, y], params=[a, b])` (coord and params optional):
a subset of what `FAST_CALL` matches, and then with the same groups (call, name, x, y,
params after coord, params alone). There `_parse_entry_full` would see the same call, so
an unknown name is `unknown_action` with the call as its text (unless the name starts
with `_`, which `_LEAD` would skip)."""
_LABEL = "\nAction:"
_BOLD_LABEL = "\n**Action:"
_THINKING = "Thinking:"


class ParsedSteps(NamedTuple):
    """The parse of every step of a batch, as columns."""

    aid: np.ndarray  # int64 action id (ActionVocab)
    x: np.ndarray  # float64; 0 where there is no coord
    y: np.ndarray
    has_coord: np.ndarray  # bool
    output: pa.Array  # string: the raw model output (null for structured actions)
    action_raw: pa.Array  # string: the Action entry text
    thinking: pa.Array  # string, null when empty
    fast: int  # steps parsed by the vectorised path


def parse_steps(steps: list[LogStep], vocab: ActionVocab) -> ParsedSteps:
    """Parse every step; equal, step by step, to `parse_log_step`."""
    n = len(steps)
    texts = [s.output for s in steps]
    output = pa.array(texts, pa.string())
    aid = np.full(n, -1, np.int64)
    x = np.zeros(n)
    y = np.zeros(n)
    has_coord = np.zeros(n, np.bool_)
    if n == 0:
        empty = pa.array([], pa.string())
        return ParsedSteps(aid, x, y, has_coord, output, empty, empty, 0)
    fast, call, thinking = _fast_path(output, vocab, aid, x, y, has_coord)
    slow = np.flatnonzero(~fast)
    if len(slow):
        entries: list[str] = []
        thoughts: list[str | None] = []
        of_parsed = vocab.of_parsed
        for i in slow.tolist():
            text = texts[i]
            parsed = _known_labels(text) if text is not None else None
            if parsed is None:
                parsed = parse_log_step(steps[i])
            aid[i] = of_parsed(parsed)
            action = parsed.action
            if action is not None and action.coord is not None:
                x[i], y[i] = action.coord
                has_coord[i] = True
            entries.append(parsed.action_text)
            thoughts.append(parsed.thinking or None)
        mask = pa.array(~fast)
        call = pc.replace_with_mask(call, mask, pa.array(entries, pa.string()))
        thinking = pc.replace_with_mask(thinking, mask, pa.array(thoughts, pa.string()))
    return ParsedSteps(aid, x, y, has_coord, output, call, thinking, int(fast.sum()))


def _known_labels(text: str) -> ParsedAction | None:
    """`parse_action(text)` for a text starting with `Thinking:` whose only `action` (any
    case) is its line-start label `\\nAction:` or `\\n**Action:`, that has none, or has two,
    both `\\nAction:`; else None (see the module docstring)."""
    if not text.startswith(_THINKING) or "\u0130" in text:
        return None
    low = text.lower()
    count = low.count("action")
    if count == 0:
        return ParsedAction(False, None, "no_action", "", text[len(_THINKING) :].strip())
    if count == 2:  # both as "\\nAction:" labels: `_find_labels` finds those two
        first = text.find(_LABEL)
        second = text.find(_LABEL, first + 1)
        if first < 0 or second < 0:
            return None
        entry = text[first + len(_LABEL) : second + 1].strip()
        thinking = text[len(_THINKING) : first].strip()
        return ParsedAction(False, None, "multiple_actions", entry, thinking)
    if count != 1:
        return None
    for label in (_LABEL, _BOLD_LABEL):
        at = text.find(label)
        if at >= 0:
            thinking = text[len(_THINKING) : at].strip()
            return _parse._parse_entry(text[at + len(label) :], thinking)
    return None


def _fast_path(
    output: pa.Array,
    vocab: ActionVocab,
    aid: np.ndarray,
    x: np.ndarray,
    y: np.ndarray,
    has_coord: np.ndarray,
) -> tuple[np.ndarray, pa.Array, pa.Array]:
    """Parse the ASCII texts starting with `Thinking:` whose only `action` (any case) is
    the label `\\nAction:` or `\\n**Action:` and whose entry `_FAST` matches with a known
    name and plain params. Fills aid/x/y/has_coord for them and returns (mask of those
    rows, entry texts, thinking texts), arbitrary at the other rows.

    Entries of the plainest shape are matched with `SIMPLE_CALL` (several times faster),
    the other gated ones with `FAST_CALL`."""
    o = pl.col("o")
    plain, bold = pl.col("plain"), pl.col("bold")
    at = pl.coalesce(plain + len(_LABEL), bold + len(_BOLD_LABEL))
    texts = pl.Series("o", output)
    frame = (
        pl.DataFrame({"o": texts})
        .with_columns(
            plain=o.str.find(_LABEL, literal=True), bold=o.str.find(_BOLD_LABEL, literal=True)
        )
        .select(
            gate=(
                o.str.starts_with(_THINKING) & (o.str.count_matches("(?i)action") == 1)
            ).fill_null(False),
            at=at,
            match=o.str.slice(at).str.extract_groups(SIMPLE_CALL),
            thinking=o.str.slice(
                len(_THINKING), pl.coalesce(plain, bold) - len(_THINKING)
            ).str.strip_chars(_WS_CHARS),
        )
    )
    gate = (
        frame["gate"].to_numpy()
        & frame["at"].is_not_null().to_numpy()
        & pc.string_is_ascii(output).fill_null(False).to_numpy(zero_copy_only=False)
    )
    keys, xs, ys, call = _groups(frame["match"])
    simple = np.array([k is not None for k in keys], np.bool_)
    rest = np.flatnonzero(gate & ~simple)
    if len(rest):
        sub = pl.DataFrame({"o": texts.gather(rest), "at": frame["at"].gather(rest)})
        sub_keys, sub_x, sub_y, sub_call = _groups(
            sub.select(o.str.slice(pl.col("at")).str.extract_groups(FAST_CALL)).to_series()
        )
        for j, i in enumerate(rest.tolist()):
            keys[i] = sub_keys[j]
        xs[rest], ys[rest] = sub_x, sub_y
        mask = np.zeros(len(keys), np.bool_)
        mask[rest] = True
        call = pc.replace_with_mask(call, pa.array(mask), sub_call)
    ids = vocab.fast_ids
    fast_aid = np.array([ids.get(k, -2) if k is not None else -1 for k in keys], np.int64)
    for i in np.flatnonzero(gate & (fast_aid == -2)).tolist():  # -2: a key not seen yet
        fast_aid[i] = ids[keys[i]] = _action_id(keys[i], vocab)
    known = gate & (fast_aid >= 0)
    aid[known] = fast_aid[known]
    unknown = gate & simple & (fast_aid == _UNKNOWN_NAME)
    aid[unknown] = vocab.of_failure("unknown_action")
    fast = known | unknown
    coord = known & ~np.isnan(xs)
    x[coord] = xs[coord]
    y[coord] = ys[coord]
    has_coord[coord] = True
    thinking = frame["thinking"].replace("", None).to_arrow().cast(pa.string())
    return fast, call, thinking


def _groups(match: pl.Series) -> tuple[list[str | None], np.ndarray, np.ndarray, pa.Array]:
    """From `_FAST`-numbered groups: the action key (`name\\0raw params`, None when there is
    no match), x, y (NaN when absent) and the call text."""
    m = pl.col("m").struct
    parts = pl.DataFrame({"m": match}).select(
        key=pl.concat_str(
            m.field("2"),
            pl.coalesce(m.field("5"), m.field("6")).fill_null(""),
            separator="\x00",
        ),
        x=m.field("3").cast(pl.Float64, strict=False),
        y=m.field("4").cast(pl.Float64, strict=False),
        call=m.field("1"),
    )
    return (
        parts["key"].to_list(),
        parts["x"].to_numpy().copy(),
        parts["y"].to_numpy().copy(),
        parts["call"].to_arrow().cast(pa.string()),
    )


_UNKNOWN_NAME = -3


def _action_id(key: str, vocab: ActionVocab) -> int:
    """`name\\0raw params` of a fast match -> action id; `_UNKNOWN_NAME` for a name that is
    not an action (and does not start with `_`); -1 when the full grammar must decide
    (params that are not plain items)."""
    name, _, raw = key.partition("\x00")
    kind = _KNOWN.get(name.lower())
    if kind is None:
        return -1 if name.startswith("_") else _UNKNOWN_NAME
    params = fast_params(raw)
    if params is None:
        return -1
    return vocab.of_action(kind, params)
