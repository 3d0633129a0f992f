"""`decode_line`: an episode line decoded straight into the kernel's step structs, only where
it is proven to agree with msgspec (`decode(episode_decoder, raw)`), declined (None) elsewhere.

Hand-worked cases for each rule (what msgspec does was measured, and is asserted beside
each), a differential test against msgspec on lines hypothesis makes and breaks, every line
of the bundled sample, and hostile lines (bounded memory, a long escaped string)."""

from __future__ import annotations

import json
import struct
from pathlib import Path

import msgspec
import pytest
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st

from replay.io import iter_lines
from replay.io._decode import decode
from replay.io._load import episode_decoder
from replay.kernel import LogLine, _logline, decline_reason, decode_line
from replay.semantics import EpisodeLog, timestamp_seconds
from replay.semantics._records import MAX_TOKENS

STEP_BYTES = _logline.STEP_BYTES

LOGS = Path(__file__).resolve().parents[3] / "logs"
TEXTS = ("output", "view", "feedback", "state")


def msgspec_log(raw: bytes) -> EpisodeLog | None:
    try:
        return decode(episode_decoder, raw)
    except (msgspec.DecodeError, msgspec.ValidationError):
        return None


def bits(x: float | None) -> bytes | None:
    return None if x is None else struct.pack("<d", x)


def expected_step(s) -> dict:
    """What `LogLine.step` must give for msgspec's `LogStep` `s`."""
    ts = s.timestamp
    fields = {name: getattr(s, name) for name in TEXTS}
    fields["ts_text"] = ts if isinstance(ts, str) else None
    fields["ts_kind"] = 0 if ts is None else 2 if isinstance(ts, str) else 1
    fields["ts"] = bits(timestamp_seconds(ts)) if fields["ts_kind"] == 1 else None
    fields["prompt"] = s.prompt_tokens
    fields["completion"] = s.completion_tokens
    fields["latency"] = bits(None if s.latency_seconds is None else float(s.latency_seconds))
    fields["ascii"] = tuple(
        n for n in (*TEXTS, "ts_text") if fields[n] is not None and fields[n].isascii()
    )
    return fields


def got_step(line: LogLine, k: int) -> dict:
    fields = line.step(k)
    for name in ("ts", "latency"):
        assert fields[name] is None or type(fields[name]) is float
        fields[name] = bits(fields[name])
    return fields


def assert_agrees(raw: bytes, line: LogLine) -> None:
    """msgspec decodes `raw` without error, to the same fields as `line`."""
    log = decode(episode_decoder, raw)
    assert log.continuation is None and all(s.action is None for s in log.steps)
    assert (line.episode_id, line.ended, len(line)) == (log.episode_id, log.ended, len(log.steps))
    assert type(line.episode_id) is str and line.raw is raw and line.continuation is None
    for k, s in enumerate(log.steps):
        assert got_step(line, k) == expected_step(s), k


def record(*steps: bytes, head: bytes = b'"episode_id":"e",') -> bytes:
    return b"{" + head + b'"steps":[' + b",".join(steps) + b"]}"


def only_step(step: bytes) -> dict:
    line = decode_line(record(step))
    assert line is not None, decline_reason(record(step))
    assert_agrees(line.raw, line)
    return line.step(0)


# Accepted: the step's JSON -> the fields step(0) gives, worked out by hand.
ACCEPTED = [
    (b"{}", {"output": None, "ts_kind": 0, "ts": None, "prompt": None, "latency": None}),
    (b'{"output":null,"view":null,"feedback":null,"state":null,"timestamp":null}', {"view": None}),
    (b'{"prompt_tokens":null,"completion_tokens":null,"latency_seconds":null}', {"prompt": None}),
    (b'{"action":null,"output":"x"}', {"output": "x", "ascii": ("output",)}),
    (b'{"state":"On","view":"top"}', {"state": "On", "view": "top"}),
    (b' { "view" :\t"a" ,\r\n"state":"b" } ', {"view": "a", "state": "b"}),
    (rb'{"output":"\" \\ \/ \b \f \n \r \t"}', {"output": '" \\ / \b \x0c \n \r \t'}),
    (rb'{"output":"\u0041\u00e9\u20AC"}', {"output": "A\u00e9\u20ac", "ascii": ()}),
    (rb'{"output":"\u0041\u0000"}', {"output": "A\x00", "ascii": ("output",)}),
    (rb'{"output":"\ud83d\ude00"}', {"output": "\U0001f600", "ascii": ()}),
    ('{"output":"é€😀\x7f"}'.encode(), {"output": "é€😀\x7f", "ascii": ()}),
    (b'{"timestamp":1767562198.474}', {"ts_kind": 1, "ts": 1767562198.474}),
    (b'{"timestamp":1}', {"ts_kind": 1, "ts": 1.0}),  # msgspec gives the float 1.0
    (b'{"timestamp":-0}', {"ts_kind": 1, "ts": 0.0}),  # an integer: 0.0, not -0.0
    (b'{"timestamp":-0.0}', {"ts_kind": 1, "ts": -0.0}),
    (b'{"timestamp":-1.5E+3}', {"ts_kind": 1, "ts": -1500.0}),
    (b'{"timestamp":"2026-01-05T10:00:00Z"}', {"ts_kind": 2, "ts_text": "2026-01-05T10:00:00Z"}),
    (b'{"prompt_tokens":0,"completion_tokens":1099511627776}', {"completion": 2**40}),
    (b'{"prompt_tokens":-0}', {"prompt": 0}),
    (b'{"latency_seconds":2}', {"latency": 2.0}),
    (b'{"latency_seconds":-0.0}', {"latency": -0.0}),  # ge=0 holds for -0.0
    (b'{"latency_seconds":0.1}', {"latency": 0.1}),
    (b'{"latency_seconds":2.2250738585072014e-308}', {"latency": 2.2250738585072014e-308}),
    (b'{"latency_seconds":123456789012345678}', {"latency": 123456789012345678.0}),
]


@pytest.mark.parametrize(("step", "fields"), ACCEPTED)
def test_a_step_is_decoded_to_msgspecs_fields(step: bytes, fields: dict) -> None:
    got = only_step(step)
    for name, value in fields.items():
        if isinstance(value, float):
            assert bits(got[name]) == bits(value), name  # -0.0 is not 0.0
        else:
            assert got[name] == value, name


@pytest.mark.parametrize(
    "raw",
    [
        b'{"episode_id":"a"}',  # no steps: []
        b'{"steps":[],"episode_id":"a"}',
        b'  {"episode_id":"a"}\r\n',  # JSON whitespace around the object
        b'{"episode_id":"a","ended":null,"continuation":null}',
        b'{"ended":"context_exceeded","episode_id":"a"}',
        rb'{"episode_id":"a","ended":"context_exceede\u0064"}',  # an escape in a value
        rb'{"episode_id":"\u00e9\"x"}',
        record(b"{}", b'{"output":"a"}', b"{ }"),
    ],
)
def test_a_record_is_decoded_to_msgspecs_fields(raw: bytes) -> None:
    line = decode_line(raw)
    assert line is not None
    assert_agrees(raw, line)


def test_the_record_fields_by_hand() -> None:
    line = decode_line(rb'{"ended":"context_exceeded","episode_id":"\u00e9\"x","steps":[{},{}]}')
    assert (line.episode_id, line.ended, len(line), line.continuation) == (
        'é"x',
        "context_exceeded",
        2,
        None,
    )
    with pytest.raises(IndexError):
        line.step(2)


# Declined: the line, why, and whether msgspec decodes it (True) or raises (False).
DECLINED = [
    (b"", "malformed", False),
    (b'{"episode_id":"a"}\x0b', "malformed", False),  # not JSON whitespace
    (b'\xef\xbb\xbf{"episode_id":"a"}', "malformed", False),  # a byte order mark
    (b'{"episode_id":"a"} {}', "malformed", False),
    (b'{"episode_id":"a",}', "malformed", False),
    (b'{"steps":[]}', "malformed", False),  # episode_id is required
    (b'{"episode_id":null}', "malformed", False),
    (b'{"episode_id":"a","steps":null}', "malformed", False),
    (b'{"episode_id":"a","ended":"other"}', "malformed", False),
    (b'{"episode_id":"a","x":1}', "unknown key", True),  # msgspec skips it
    (b'{"episode_id":"a","episode_id":"b"}', "duplicate key", True),  # msgspec keeps "b"
    (rb'{"episode_id":"a","\u0073teps":[]}', "escape", True),  # msgspec reads "steps"
    (
        b'{"episode_id":"a","continuation":{"prefix_steps":0,"fixed":false,"continued":false,'
        b'"source_success":true}}',
        "continuation",
        True,
    ),
    (record(b'{"action":{"type":"Press"}}'), "structured action", True),
    (record(b'{"view":"a","view":"b"}'), "duplicate key", True),
    (record(b'{"Output":"a"}'), "unknown key", True),
    (record(b"[]"), "malformed", False),
    (record(b'{"output":1}'), "malformed", False),
    (record(b'{"timestamp":true}'), "malformed", False),
    (record(b'{"prompt_tokens":1.0}'), "malformed", False),  # a float, even 1.0
    (record(b'{"prompt_tokens":1e2}'), "malformed", False),
    (record(b'{"prompt_tokens":-1}'), "malformed", False),
    (record(b'{"prompt_tokens":1099511627777}'), "malformed", False),  # 2**40 + 1
    (record(b'{"prompt_tokens":01}'), "malformed", False),  # a leading zero
    (record(b'{"latency_seconds":-1}'), "malformed", False),
    (record(b'{"latency_seconds":-0.5}'), "malformed", False),
    (record(b'{"latency_seconds":.5}'), "malformed", False),
    (record(b'{"latency_seconds":1.}'), "malformed", False),
    (record(b'{"latency_seconds":+1}'), "malformed", False),
    (record(b'{"latency_seconds":NaN}'), "malformed", False),
    (record(b'{"latency_seconds":1e400}'), "number", False),  # out of range
    (record(b'{"latency_seconds":1e-400}'), "number", True),  # rounds to 0.0
    (record(b'{"latency_seconds":5e-324}'), "number", True),  # subnormal
    (record(b'{"timestamp":1234567890123456789}'), "number", True),  # 19 digits
    (record(b'{"timestamp":1.' + b"0" * 40 + b"}"), "number", True),  # 41 digits
    (record(b'{"timestamp":1e00001}'), "number", True),  # a 5-digit exponent
    (record(rb'{"output":"\ud800"}'), "escape", False),  # a lone surrogate
    (record(rb'{"output":"\udc00\ud800"}'), "escape", False),
    (record(rb'{"output":"\ud83d\u0041"}'), "escape", False),
    (record(rb'{"output":"\a"}'), "malformed", False),
    (record(rb'{"output":"\u004G"}'), "malformed", False),
    (record(b'{"output":"a\x01"}'), "malformed", False),  # a raw control character
    (record(b'{"output":"a\x00"}'), "malformed", False),
    (record(b'{"output":"a'), "malformed", False),
    (record(b'{"output":"\xed\xa0\x80"}'), "invalid UTF-8", False),  # a surrogate
    (record(b'{"output":"\xc0\x80"}'), "invalid UTF-8", False),  # overlong
    (record(b'{"output":"\xe0\x9f\xbf"}'), "invalid UTF-8", False),  # overlong
    (record(b'{"output":"\xf4\x90\x80\x80"}'), "invalid UTF-8", False),  # past U+10FFFF
    (record(b'{"output":"\xe2\x82"}'), "invalid UTF-8", False),  # cut
    (record(b'{"output":"\x80"}'), "invalid UTF-8", False),
]


def test_the_bound_on_tokens_is_the_records() -> None:
    assert MAX_TOKENS == 2**40  # spelled 1 << 40 in _logline.pyx
    assert only_step(b'{"prompt_tokens":%d}' % MAX_TOKENS)["prompt"] == MAX_TOKENS
    assert decode_line(record(b'{"prompt_tokens":%d}' % (MAX_TOKENS + 1))) is None


@pytest.mark.parametrize(("raw", "why", "msgspec_decodes"), DECLINED)
def test_a_line_in_doubt_is_declined(raw: bytes, why: str, msgspec_decodes: bool) -> None:
    assert decode_line(raw) is None
    assert decline_reason(raw) == why
    assert (msgspec_log(raw) is not None) == msgspec_decodes


def test_the_steps_are_bounded_by_the_lines_length() -> None:
    """At most len(raw) // STEP_BYTES + 64 steps: 65 `{}` steps on a line of 223 bytes are
    (223 // 184 + 64 = 65), 66 on one of 226 are not (226 // 184 + 64 = 65)."""
    assert STEP_BYTES == 184
    ok, over = record(*[b"{}"] * 65), record(*[b"{}"] * 66)
    assert (len(ok), len(over)) == (223, 226)
    assert len(decode_line(ok)) == 65
    assert decode_line(over) is None and decline_reason(over) == "too many steps"
    assert msgspec_log(over) is not None


def test_a_long_line_of_empty_steps_is_declined() -> None:
    raw = record(*[b"{}"] * 1_000_000)  # 3 MB, a million steps: 184 MB of structs
    assert decline_reason(raw) == "too many steps"
    assert decode_line(raw) is None


def test_a_megabyte_string_with_escapes_is_decoded() -> None:
    text = ('Thinking: "a\\b"\n\tté€😀\x00/' * 40_000)[:1_000_000]
    raw = json.dumps({"episode_id": "e", "steps": [{"output": text, "view": text[:9]}]}).encode()
    line = decode_line(raw)
    assert line is not None and line.step(0)["output"] == text
    assert_agrees(raw, line)


def test_every_line_of_the_bundled_sample_agrees_with_msgspec() -> None:
    """The 312 lines of each of the eight model runs are decoded and agree; the 166 of the
    human run are declined, each for its structured actions (the kernel reads them from
    msgspec's `LogStep`)."""
    counts: dict[tuple[str, str | None], int] = {}
    for path in sorted((LOGS / "runs").glob("*/episodes.jsonl.gz")):
        for _, raw in iter_lines(path):
            line = decode_line(raw)
            why = decline_reason(raw)
            key = ("human" if path.parent.name == "sim-human" else "model", why)
            counts[key] = counts.get(key, 0) + 1
            if line is not None:
                assert why is None
                assert_agrees(raw, line)
            else:
                assert any(s.action is not None for s in msgspec_log(raw).steps)
    assert counts == {("model", None): 8 * 312, ("human", "structured action"): 166}


# The differential test: near-valid records, written in many ways, some of them broken.

_ESCAPES = {
    '"': '\\"',
    "\\": "\\\\",
    "/": "\\/",
    "\b": "\\b",
    "\f": "\\f",
    "\n": "\\n",
    "\r": "\\r",
    "\t": "\\t",
}


def _spell_char(c: str, how: int) -> str:
    """One character of a JSON string: raw where JSON allows it (how 0), else escaped."""
    if how == 0 and c not in '"\\' and c >= " ":
        return c
    if how == 1 and c in _ESCAPES:
        return _ESCAPES[c]
    code = ord(c)
    if code >= 0x10000:
        code -= 0x10000
        pair = (0xD800 + (code >> 10), 0xDC00 + (code & 0x3FF))
        return "".join(f"\\u{u:04x}" if how == 2 else f"\\u{u:04X}" for u in pair)
    return f"\\u{code:04x}" if how != 3 else f"\\u{code:04X}"


_CHARS = st.characters(codec="utf-8")  # no surrogates: a str that is UTF-8
_STRING = st.lists(st.tuples(_CHARS, st.integers(0, 3)), max_size=12).map(
    lambda cs: '"' + "".join(_spell_char(c, how) for c, how in cs) + '"'
)
_WS = st.sampled_from(["", "", "", " ", "\n", "\t", "\r\n ", "  "])
_FLOAT_SPELLINGS = st.sampled_from(["%r", "%.17g", "%.3e", "%.20E", "%.1f", "%g", "%.25e"])
_FLOAT = st.tuples(st.floats(allow_nan=False, allow_infinity=False), _FLOAT_SPELLINGS).map(
    lambda t: repr(t[0]) if t[1] == "%r" else t[1] % t[0]
)
_WIDE_INT = st.one_of(st.integers(-(10**20), 10**20), st.integers(-9, 9)).map(str) | st.just("-0")


def _plain_number(s: str, low: float | None = None) -> bool:
    """A number spelled as the decoder takes it: at most 40 digits (18 for an integer), a
    normal float or zero, at least `low`."""
    mantissa, _, exponent = s.lstrip("-").lower().partition("e")
    digits = sum(c.isdigit() for c in mantissa)
    x = float(s)
    if "." not in s and "e" not in s.lower():
        return digits <= 18 and (low is None or int(s) >= low)
    fine = x == 0 and mantissa.strip("0.") == "" or 2.2250738585072014e-308 <= abs(x) < 1e308
    return digits <= 40 and len(exponent.lstrip("+-")) <= 4 and fine and (low is None or x >= low)


@st.composite
def _value(draw, key: str, plain: bool) -> str:
    """A JSON value for `key`: one msgspec takes and the decoder decodes (plain), or, now and
    then, one that either may not."""
    if not plain and draw(st.integers(0, 24)) == 0:  # a wrong or odd value
        odd = ["true", "1", "-1", '"x"', "[]", "{}", "1.0", "1e999", "01", '{"type":"Press"}']
        odd += [r'"\ud800"', r'"a\udc00"', r'"\ud83d\u0041"', r'"\u00"', '"\x7f\x1f"', "5e-324"]
        return draw(st.sampled_from(odd))
    if draw(st.integers(0, 5)) == 0:
        return "null"
    if key in TEXTS or key == "episode_id":
        return draw(_STRING)
    if key in ("ended", "action", "continuation"):
        return '"context_exceeded"' if key == "ended" else "null"
    if key == "timestamp" and draw(st.booleans()):
        return draw(_STRING)
    if key in ("prompt_tokens", "completion_tokens"):
        number = st.integers(0, 2**40).map(str) | (st.nothing() if plain else _WIDE_INT)
    else:
        number = _FLOAT | _WIDE_INT
        if plain:
            low = 0 if key == "latency_seconds" else None
            number = number.filter(lambda s: _plain_number(s, low))
    return draw(number)


_STEP_KEYS = [
    *TEXTS,
    "timestamp",
    "prompt_tokens",
    "completion_tokens",
    "latency_seconds",
    "action",
]


@st.composite
def _object(draw, keys: list[str], plain: bool, extra: dict[str, str]) -> str:
    chosen = draw(st.permutations(keys))[: draw(st.integers(0, len(keys)))]
    members = [(k, draw(_value(k, plain))) for k in chosen]
    members += list(extra.items())
    if not plain and draw(st.integers(0, 24)) == 0:
        members.append(
            draw(st.sampled_from([("x", "1"), ("output", '"dup"'), ("episode_id", '"d"')]))
        )
    members = draw(st.permutations(members))
    ws = draw(_WS)
    return (
        "{"
        + ws
        + ",".join(f'{draw(_WS)}"{k}"{draw(_WS)}:{draw(_WS)}{v}{draw(_WS)}' for k, v in members)
        + "}"
    )


@st.composite
def lines(draw, plain: bool) -> bytes:
    steps = [draw(_object(_STEP_KEYS, plain, {})) for _ in range(draw(st.integers(0, 4)))]
    extra = {"episode_id": draw(_STRING), "steps": "[" + ",".join(steps) + "]"}
    text = draw(_WS) + draw(_object(["ended", "continuation"], plain, extra)) + draw(_WS)
    raw = text.encode("utf-8")
    if not plain:
        for _ in range(draw(st.sampled_from([0, 0, 0, 1, 2]))):  # cut, change, insert
            at = draw(st.integers(0, len(raw)))
            how = draw(st.integers(0, 2))
            byte = bytes([draw(st.integers(0, 255))])
            raw = raw[:at] if how == 0 else raw[:at] + byte + raw[at + (how == 1) :]
    return raw


@settings(max_examples=800, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(lines(plain=False))
def test_every_line_decoded_agrees_with_msgspec(raw: bytes) -> None:
    event(f"declined: {decline_reason(raw)}")  # pytest --hypothesis-show-statistics
    line = decode_line(raw)
    if line is not None:
        assert_agrees(raw, line)


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(lines(plain=True))
def test_plain_well_formed_lines_are_decoded(raw: bytes) -> None:
    line = decode_line(raw)
    assert line is not None, (decline_reason(raw), raw)
    assert_agrees(raw, line)


@settings(max_examples=400, deadline=None)
@given(
    st.integers(0, 10**16),
    st.integers(-25, 25),
    st.integers(0, 16),
    st.sampled_from(["e", "E", "e+", "e-0"]),
    st.booleans(),
)
def test_decimals_are_rounded_as_msgspec_rounds_them(
    mantissa: int, exponent: int, point: int, e: str, negative: bool
) -> None:
    """A decimal of up to 17 digits, the point anywhere, within and past the exact fast path
    (15 digits, powers of ten to 22): the float msgspec gives, bit for bit."""
    digits = str(mantissa)
    point = min(point, len(digits) - 1)
    text = digits[: len(digits) - point] + ("." + digits[len(digits) - point :] if point else "")
    spelled = (
        ("-" if negative else "") + text + (f"{e}{exponent}" if exponent >= 0 else f"e{exponent}")
    )
    raw = record(b'{"timestamp":%s,"latency_seconds":%s}' % (spelled.encode(), text.encode()))
    line = decode_line(raw)
    assert line is not None, (spelled, decline_reason(raw))
    assert_agrees(raw, line)
    assert bits(line.step(0)["ts"]) == bits(float(spelled))


def test_every_code_point_through_its_escape() -> None:
    """Each of the 1,112,064 code points that are not surrogates, as `\\uXXXX` (a surrogate
    pair past U+FFFF), is decoded to its UTF-8."""
    wrong = []
    for code in range(0x110000):
        if 0xD800 <= code <= 0xDFFF:
            continue
        if code < 0x10000:
            escape = f"\\u{code:04x}"
        else:
            high, low = divmod(code - 0x10000, 0x400)
            escape = f"\\u{0xD800 + high:04x}\\u{0xDC00 + low:04X}"
        line = decode_line(b'{"episode_id":"' + escape.encode() + b'"}')
        if line is None or line.episode_id != chr(code):
            wrong.append(code)
    assert wrong == []
