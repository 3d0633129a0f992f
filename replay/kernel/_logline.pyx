# cython: language_level=3, boundscheck=False, wraparound=False, initializedcheck=False, cdivision=True
"""Episode records decoded straight into the kernel's step structs (see _logline.pxd).

`decode_line` is a second reader of PROTOCOL §1.4's episode records, for speed only: it
returns a `LogLine` only for a line msgspec (`replay.io._decode.decode(episode_decoder, raw)`)
decodes without error to an `EpisodeLog` with no continuation and no structured action, every
field equal to msgspec's; on any doubt it returns None and msgspec decodes the line (so every
error message stays msgspec's). tests/replay/kernel/test_logline.py proves the agreement.

What it accepts, as msgspec decodes it (measured with msgspec 0.22):
- JSON whitespace (space, tab, CR, LF) around the object and between tokens; keys in any order;
- strings with the escapes of JSON (a surrogate pair becomes one 4-byte UTF-8 character) and
  UTF-8 exactly as Python's codec takes it (no overlong forms, surrogates or code points past
  U+10FFFF); a raw control character is malformed;
- tokens: an integer from 0 to 2**40 (`-0` is 0); latency: an integer (made a float) or a
  decimal >= 0 (`-0.0` stays -0.0); timestamp: any integer (made a float: `-0` gives 0.0,
  not -0.0) or decimal, or a string.
Declined: integers of more than 18 digits, decimals of more than 40 digits or with an exponent
of more than 4 digits, and decimals that overflow or round to a subnormal or to zero from a
non-zero mantissa; an escape in a key; a `\\u` escape of a lone surrogate (msgspec's error).

Bounds (PROTOCOL §1.5): time linear in the line; memory for the steps at most the line's
length plus `_SPARE_STEPS` structs (a line of more, short, steps such as `{}` is declined);
unescaped strings are copied into one buffer of the line's length, allocated on the first
escape (an escape is longer than what it stands for, so they all fit)."""

from cpython.exc cimport PyErr_Clear, PyErr_Occurred
from cpython.object cimport PyObject
from cpython.unicode cimport PyUnicode_DecodeUTF8
from libc.math cimport fabs, isfinite
from libc.stdint cimport int64_t
from libc.stdlib cimport free, malloc, realloc
from libc.string cimport memcmp, memcpy, memset

from ..semantics import CONTEXT_EXCEEDED


cdef extern from "Python.h":
    double PyOS_string_to_double(const char* s, char** endptr, PyObject* overflow_exception)

cdef extern from *:
    """
    /* The first byte from i that a JSON string's scan stops at: a quote (0x22), a backslash
       (0x5C), a control character or a byte of a non-ASCII character (as signed bytes, both
       are below 0x20); s[n] is a NUL, so the scan stops there. With SSE2 (every x86-64)
       sixteen bytes at a time, then (and without SSE2) byte by byte. */
    #if defined(__SSE2__)
    #include <emmintrin.h>
    #endif
    static inline Py_ssize_t logline_plain(const unsigned char* s, Py_ssize_t i, Py_ssize_t n) {
    #if defined(__SSE2__)
        const __m128i quote = _mm_set1_epi8(0x22), backslash = _mm_set1_epi8(0x5C);
        const __m128i space = _mm_set1_epi8(0x20);
        while (i + 16 <= n) {
            __m128i v = _mm_loadu_si128((const __m128i*)(s + i));
            __m128i stop = _mm_or_si128(
                _mm_or_si128(_mm_cmpeq_epi8(v, quote), _mm_cmpeq_epi8(v, backslash)),
                _mm_cmplt_epi8(v, space));
            int mask = _mm_movemask_epi8(stop);
            if (mask) return i + __builtin_ctz(mask);
            i += 16;
        }
    #endif
        while (s[i] != 0x22 && s[i] != 0x5C && s[i] >= 0x20 && s[i] < 0x80) i++;
        return i;
    }
    """
    Py_ssize_t _plain "logline_plain" (
        const unsigned char* s, Py_ssize_t i, Py_ssize_t n) noexcept nogil

cdef extern from "float.h":
    double DBL_MIN
    int FLT_EVAL_METHOD     # 0: each double operation rounds to a double (SSE2, not x87)

cdef int64_t _MAX_TOKENS = 1 << 40  # MAX_TOKENS of replay.semantics' records (a test checks)
cdef bytes _ENDED = CONTEXT_EXCEEDED.encode()  # the one value of `ended` but null


cdef enum:
    _SPARE_STEPS = 64       # step structs any line may have beyond its length in bytes
    _MAX_INT_DIGITS = 18    # an integer of at most 18 digits fits an int64, and converts exactly
    _MAX_DIGITS = 40        # digits of a decimal's mantissa
    _MAX_EXP_DIGITS = 4     # digits of a decimal's exponent


# Why a line was declined (`decline_reason`): the first doubt met, in reading order.
cdef enum:
    _OK = 0
    _MALFORMED = 1     # not JSON, or not an episode record (msgspec raises an error)
    _UNKNOWN_KEY = 2   # msgspec would skip it
    _DUPLICATE_KEY = 3  # msgspec would keep the last
    _ACTION = 4        # a structured action (the kernel reads msgspec's LogStep)
    _CONTINUATION = 5  # a continuation run's record
    _NUMBER = 6        # a number outside those decoded here
    _ESCAPE = 7        # an escape in a key, or of a lone surrogate
    _UTF8 = 8          # bytes that are not UTF-8
    _STEPS = 9         # more steps than the bound on memory allows

REASONS = (
    None, "malformed", "unknown key", "duplicate key", "structured action", "continuation",
    "number", "escape", "invalid UTF-8", "too many steps",
)
"""`decline_reason`'s answers, by reason code (None: accepted)."""

STEP_BYTES = sizeof(StepIn)
"""Bytes of one decoded step (the bound on a line's steps counts them)."""


# Step keys (bits of a step's `seen`) and record keys.
cdef enum:
    _K_OUTPUT, _K_ACTION, _K_VIEW, _K_FEEDBACK, _K_STATE, _K_TIMESTAMP, _K_PROMPT,
    _K_COMPLETION, _K_LATENCY, _K_EPISODE_ID, _K_STEPS, _K_ENDED, _K_CONTINUATION


cdef StepIn _NO_STEP  # all zeros: every field None
cdef const char* _KEY_NAME[13]
cdef Py_ssize_t _KEY_SIZE[13]
cdef tuple _KEY_BYTES = (  # in the order of the `_K_*`; held here, for `_KEY_NAME`
    b"output", b"action", b"view", b"feedback", b"state", b"timestamp", b"prompt_tokens",
    b"completion_tokens", b"latency_seconds", b"episode_id", b"steps", b"ended", b"continuation",
)
# A step's keys (row 0) and a record's (row 1) by their first byte (-1: no key starts so).
cdef signed char _BY_FIRST[2][256]
for _c in range(13):
    _KEY_NAME[_c] = <bytes>_KEY_BYTES[_c]
    _KEY_SIZE[_c] = len(_KEY_BYTES[_c])
for _c in range(256):
    _BY_FIRST[0][_c] = _BY_FIRST[1][_c] = -1
for _c in range(_K_EPISODE_ID):  # the step keys, whose first bytes all differ
    _BY_FIRST[0][<unsigned char>_KEY_NAME[_c][0]] = _c
for _c in (_K_EPISODE_ID, _K_STEPS, _K_CONTINUATION):  # and ended: see _known_key
    _BY_FIRST[1][<unsigned char>_KEY_NAME[_c][0]] = _c


cdef struct Parser:
    const unsigned char* s  # the line; s[n] is the NUL every bytes object ends with
    Py_ssize_t n
    Py_ssize_t i            # the next byte to read
    char* buf               # unescaped strings (NULL until the first escape)
    Py_ssize_t used
    StepIn* steps
    Py_ssize_t n_steps
    Py_ssize_t cap
    Text episode_id
    bint ended
    int why


cdef struct Num:
    bint is_int
    int64_t ival            # an integer's value
    double fval             # the value as a float (an integer's too)


# What a one-letter escape stands for, by its letter (0: none, or the `u` of `\uXXXX`).
cdef unsigned char _SHORT_ESCAPE[256]
for _c, _to in {34: 34, 92: 92, 47: 47, 98: 8, 102: 12, 110: 10, 114: 13, 116: 9}.items():
    _SHORT_ESCAPE[_c] = _to

# A hex digit's value by its byte, -1 for every other byte.
cdef signed char _HEX[256]
for _c in range(256):
    _HEX[_c] = int(chr(_c), 16) if chr(_c) in "0123456789abcdefABCDEF" else -1

# Exact powers of ten (10**22 is the largest a double holds exactly).
cdef double _POW10[23]
for _c in range(23):
    _POW10[_c] = float(f"1e{_c}")


cdef class LogLine:
    def __dealloc__(self):
        free(self.steps)
        free(self.buf)

    @property
    def continuation(self):
        return None  # a line with a continuation is declined (msgspec decodes it)

    def __len__(self):
        return self.n_steps

    def step(self, Py_ssize_t k):
        """The k-th step's fields as Python values, to inspect and test the structs: a dict of
        `output`, `view`, `feedback`, `state`, `ts_text` (str or None), `ts_kind` (TS_NONE 0,
        TS_NUMBER 1, TS_TEXT 2), `ts` (float, or None unless TS_NUMBER), `prompt`,
        `completion` (int or None), `latency` (float or None), and `ascii`: the names of the
        texts flagged all-ASCII."""
        if k < 0 or k >= self.n_steps:
            raise IndexError(f"step {k} of a line of {self.n_steps}")
        cdef StepIn* st = &self.steps[k]
        cdef Text* texts[5]
        texts[:] = [&st.output, &st.view, &st.feedback, &st.state, &st.ts_text]
        names = ("output", "view", "feedback", "state", "ts_text")
        fields = {names[j]: _text(texts[j]) for j in range(5)}
        fields["ts_kind"] = st.ts_kind
        fields["ts"] = st.ts if st.ts_kind == TS_NUMBER else None
        fields["prompt"] = st.prompt if st.has_prompt else None
        fields["completion"] = st.completion if st.has_completion else None
        fields["latency"] = st.latency if st.has_latency else None
        fields["ascii"] = tuple(
            names[j] for j in range(5) if texts[j].data != NULL and texts[j].ascii
        )
        return fields


cdef object _text(Text* t):
    if t.data == NULL:
        return None
    return PyUnicode_DecodeUTF8(t.data, t.size, NULL)


def decode_line(bytes raw not None):
    """The line as a `LogLine`, or None: msgspec decodes it (every doubt is a None)."""
    cdef Parser p
    cdef LogLine line
    if not _parse(raw, &p):
        free(p.steps)
        free(p.buf)
        return None
    _fit(&p)
    line = LogLine.__new__(LogLine)
    line.steps, line.n_steps, line.buf = p.steps, p.n_steps, p.buf  # owned (and freed) here
    line.raw = raw
    line.ended = CONTEXT_EXCEEDED if p.ended else None
    line.episode_id = PyUnicode_DecodeUTF8(p.episode_id.data, p.episode_id.size, NULL)
    return line


cdef void _fit(Parser* p) noexcept nogil:
    """The steps cut to their number: they were allocated by doubling, and a batch keeps many
    lines (a shrunk block stays in place; the freed tail serves the next line. Measured:
    without it, glibc returns a batch's memory to the system and takes it back page by page
    on the next batch: 30 times the page faults and twice the time)."""
    cdef StepIn* steps
    if 0 < p.n_steps < p.cap:
        steps = <StepIn*>realloc(p.steps, p.n_steps * sizeof(StepIn))
        if steps != NULL:
            p.steps = steps


def decline_reason(bytes raw not None):
    """Why `decode_line` declines the line (one of `REASONS`), or None when it accepts it."""
    cdef Parser p
    _parse(raw, &p)
    free(p.steps)
    free(p.buf)
    return REASONS[p.why]


cdef bint _parse(bytes raw, Parser* p) noexcept:
    memset(p, 0, sizeof(Parser))
    p.s = <const unsigned char*><const char*>raw
    p.n = len(raw)
    _ws(p)
    if not _record(p):
        return False
    _ws(p)
    if p.i != p.n:
        return _fail(p, _MALFORMED)
    return True


cdef inline bint _fail(Parser* p, int why) noexcept nogil:
    p.why = why
    return False


cdef inline void _ws(Parser* p) noexcept nogil:
    cdef const unsigned char* s = p.s
    cdef Py_ssize_t i = p.i
    while s[i] == 32 or s[i] == 10 or s[i] == 13 or s[i] == 9:
        i += 1
    p.i = i


cdef inline bint _null(Parser* p) noexcept nogil:
    if p.i + 4 <= p.n and memcmp(p.s + p.i, b"null", 4) == 0:
        p.i += 4
        return True
    return False


cdef bint _record(Parser* p) noexcept:
    """The record's object: `episode_id` (a string), `steps`, `ended` and `continuation`."""
    cdef int key, seen = 0, members = _open(p, 123, 125)
    cdef Text ended
    if members < 0:
        return False
    if members:
        while True:
            key = _new_key(p, &seen, True)
            if key < 0:
                return False
            if key == _K_EPISODE_ID:
                if not _text_value(p, &p.episode_id):
                    return False
            elif key == _K_STEPS:
                if not _steps(p):
                    return False
            elif key == _K_ENDED:
                if not _null(p):
                    if not _text_value(p, &ended):
                        return False
                    if ended.size != len(_ENDED) or memcmp(ended.data, <char*>_ENDED, ended.size):
                        return _fail(p, _MALFORMED)
                    p.ended = True
            elif not _null(p):  # continuation
                return _fail(p, _CONTINUATION)
            if not _next(p, 125):
                return _fail(p, p.why if p.why else _MALFORMED)
            if p.s[p.i - 1] == 125:
                break
    if not seen & (1 << _K_EPISODE_ID):
        return _fail(p, _MALFORMED)
    return True


cdef inline bint _next(Parser* p, unsigned char close) noexcept nogil:
    """After a member or an element: past a `,` (True), or past `close` (True), or False."""
    _ws(p)
    if p.s[p.i] == 44:
        p.i += 1
        _ws(p)
        return True
    if p.s[p.i] == close:
        p.i += 1
        return True
    return False


cdef int _key(Parser* p, bint record) noexcept nogil:
    """A key and its `:`, as a `_K_*` (-1 and `why` set when it is not a key of the object)."""
    cdef const unsigned char* s = p.s
    cdef Py_ssize_t i = p.i + 1
    cdef int key
    if s[p.i] != 34:
        _fail(p, _MALFORMED)
        return -1
    key = _known_key(s + i, p.n - i, record)
    if key < 0:  # why not: an escape, the end of the line, or a name not of the object
        while s[i] != 34 and s[i] != 92 and s[i] >= 32:
            i += 1
        _fail(p, _ESCAPE if s[i] == 92 else _MALFORMED if s[i] < 32 else _UNKNOWN_KEY)
        return -1
    p.i = i + _KEY_SIZE[key] + 1
    _ws(p)
    if s[p.i] != 58:
        _fail(p, _MALFORMED)
        return -1
    p.i += 1
    _ws(p)
    return key


cdef inline int _new_key(Parser* p, int* seen, bint record) noexcept nogil:
    """The next key of an object (`_key`), marked in `seen`; -1 and `why` set when it is not
    a key of the object or was seen before (msgspec would keep the last value)."""
    cdef int key = _key(p, record)
    if key < 0:
        return -1
    if seen[0] & (1 << key):
        _fail(p, _DUPLICATE_KEY)
        return -1
    seen[0] |= 1 << key
    return key


cdef int _known_key(const unsigned char* k, Py_ssize_t room, bint record) noexcept nogil:
    """The key whose name and closing quote start at `k` (`room` bytes before the line's
    end), or -1: the candidate by its first byte or two, then compared whole."""
    cdef int key = _BY_FIRST[record][k[0]]
    if key == _K_EPISODE_ID and k[1] != 112:  # "ended", the other record key in e
        key = _K_ENDED
    if key < 0 or room <= _KEY_SIZE[key] or k[_KEY_SIZE[key]] != 34:
        return -1
    return key if memcmp(k, _KEY_NAME[key], _KEY_SIZE[key]) == 0 else -1


cdef bint _steps(Parser* p) noexcept:
    """`steps`: an array of step objects, each decoded into the next `StepIn`."""
    cdef int members = _open(p, 91, 93)
    if members <= 0:
        return members == 0
    while True:
        if p.n_steps == p.cap and not _grow(p):
            return False
        if not _step(p, &p.steps[p.n_steps]):
            return False
        p.n_steps += 1
        if not _next(p, 93):
            return _fail(p, _MALFORMED)
        if p.s[p.i - 1] == 93:
            return True


cdef inline int _open(Parser* p, unsigned char opener, unsigned char closer) noexcept nogil:
    """Past an array's or an object's opener: 1 when members follow, 0 past the closer of an
    empty one, -1 (`why` set) when there is none."""
    if p.s[p.i] != opener:
        _fail(p, _MALFORMED)
        return -1
    p.i += 1
    _ws(p)
    if p.s[p.i] == closer:
        p.i += 1
        return 0
    return 1


cdef bint _grow(Parser* p) noexcept nogil:
    """Room for more steps, within the line's length plus `_SPARE_STEPS` structs."""
    cdef Py_ssize_t most = p.n // <Py_ssize_t>sizeof(StepIn) + _SPARE_STEPS
    cdef Py_ssize_t cap = min(max(2 * p.cap, 16), most)
    cdef StepIn* grown
    if cap <= p.cap:
        return _fail(p, _STEPS)
    grown = <StepIn*>realloc(p.steps, cap * sizeof(StepIn))
    if grown == NULL:
        return _fail(p, _STEPS)
    p.steps, p.cap = grown, cap
    return True


cdef bint _step(Parser* p, StepIn* st) noexcept:
    """One step object into `st` (absent fields stay None: NULL texts, TS_NONE, no numbers)."""
    cdef int key, seen = 0, members = _open(p, 123, 125)
    st[0] = _NO_STEP
    if members <= 0:
        return members == 0
    while True:
        key = _new_key(p, &seen, False)
        if key < 0:
            return False
        if not _step_value(p, st, key):
            return _fail(p, p.why if p.why else _MALFORMED)
        if not _next(p, 125):
            return _fail(p, _MALFORMED)
        if p.s[p.i - 1] == 125:
            return True


cdef bint _step_value(Parser* p, StepIn* st, int key) noexcept:
    cdef Num num
    if _null(p):
        return True
    if key == _K_ACTION:
        return _fail(p, _ACTION)
    if key <= _K_STATE:  # output, view, feedback, state
        return _text_value(p, _texts(st, key))
    if key == _K_TIMESTAMP and p.s[p.i] == 34:
        st.ts_kind = TS_TEXT
        return _string(p, &st.ts_text)
    if not _number(p, &num):
        return False
    if key == _K_TIMESTAMP:
        st.ts_kind, st.ts = TS_NUMBER, num.fval
    elif key == _K_LATENCY:  # a float >= 0 (an integer is made one; -0.0 is >= 0)
        st.has_latency, st.latency = True, num.fval
        if not num.fval >= 0:
            return _fail(p, _MALFORMED)
    else:  # tokens: an integer from 0 to 2**40 (a float, even 1.0, is msgspec's error)
        if not num.is_int or num.ival < 0 or num.ival > _MAX_TOKENS:
            return _fail(p, _MALFORMED)
        if key == _K_PROMPT:
            st.has_prompt, st.prompt = True, num.ival
        else:
            st.has_completion, st.completion = True, num.ival
    return True


cdef inline Text* _texts(StepIn* st, int key) noexcept nogil:
    """A step's text field by its key (`_K_OUTPUT`, `_K_VIEW`, `_K_FEEDBACK`, `_K_STATE`)."""
    return &st.output if key == _K_OUTPUT else &st.view if key == _K_VIEW else (
        &st.feedback if key == _K_FEEDBACK else &st.state)


cdef inline bint _text_value(Parser* p, Text* out) noexcept nogil:
    if p.s[p.i] != 34:
        return _fail(p, _MALFORMED)
    return _string(p, out)


cdef bint _number(Parser* p, Num* out) noexcept:
    """A JSON number: an integer of at most 18 digits exactly, a decimal correctly rounded
    (as msgspec rounds it; unusual ones are declined): by Clinger's fast path where it is
    exact, else by `PyOS_string_to_double`."""
    cdef const unsigned char* s = p.s
    cdef Py_ssize_t start = p.i, i = p.i, digits = 0, frac = 0, exp_start
    cdef bint negative = s[i] == 45, nonzero = False, decimal = False, exp_negative = False
    cdef int64_t mantissa = 0, exponent = 0
    i += negative
    if s[i] == 48 and _digit(s[i + 1]) or not _digit(s[i]):
        return _fail(p, _MALFORMED)  # a leading zero, or no digit
    while True:
        while _digit(s[i]):
            if digits < _MAX_INT_DIGITS:  # no overflow: longer integers are declined
                mantissa = mantissa * 10 + (s[i] - 48)
                frac += decimal
            nonzero |= s[i] != 48
            digits += 1
            i += 1
        if s[i] != 46 or decimal:
            break
        decimal = True
        i += 1
        if not _digit(s[i]):
            return _fail(p, _MALFORMED)
    if s[i] == 101 or s[i] == 69:
        decimal = True
        i += 1
        exp_negative = s[i] == 45
        i += s[i] == 43 or s[i] == 45
        exp_start = i
        while _digit(s[i]):
            if i - exp_start < _MAX_EXP_DIGITS:
                exponent = exponent * 10 + (s[i] - 48)
            i += 1
        if i == exp_start:
            return _fail(p, _MALFORMED)
        if i - exp_start > _MAX_EXP_DIGITS:
            return _fail(p, _NUMBER)
    p.i = i
    out.is_int = not decimal
    if not decimal:
        if digits > _MAX_INT_DIGITS:
            return _fail(p, _NUMBER)
        out.ival = -mantissa if negative else mantissa
        out.fval = <double>out.ival  # as msgspec makes an integer a float: -0 gives 0.0
        return True
    if digits > _MAX_DIGITS:
        return _fail(p, _NUMBER)
    exponent = (-exponent if exp_negative else exponent) - frac
    if digits <= 15 and -22 <= exponent <= 22 and FLT_EVAL_METHOD == 0:
        # Clinger's fast path: the mantissa (< 10**15 < 2**53) and 10**|exponent| are exact
        # doubles, so one IEEE product or quotient is the correctly rounded value.
        if exponent >= 0:
            out.fval = mantissa * _POW10[exponent]
        else:
            out.fval = mantissa / _POW10[-exponent]
        out.fval = -out.fval if negative else out.fval
        return True
    return _slow_decimal(p, out, start, nonzero)


cdef inline bint _digit(unsigned char c) noexcept nogil:
    return 48 <= c <= 57


cdef bint _slow_decimal(Parser* p, Num* out, Py_ssize_t start, bint nonzero) noexcept:
    """The decimal from `start` to `p.i` by `PyOS_string_to_double` (David Gay's correctly
    rounded strtod, as Python's float()); declined when it overflows, or rounds to a
    subnormal or to zero from a non-zero mantissa."""
    cdef char* end
    out.fval = PyOS_string_to_double(<const char*>(p.s + start), &end, NULL)
    if PyErr_Occurred() != NULL:
        PyErr_Clear()
        return _fail(p, _NUMBER)
    if <const unsigned char*>end != p.s + p.i or not isfinite(out.fval):
        return _fail(p, _NUMBER)
    if (out.fval != 0 and fabs(out.fval) < DBL_MIN) or (out.fval == 0 and nonzero):
        return _fail(p, _NUMBER)
    return True


cdef bint _string(Parser* p, Text* out) noexcept nogil:
    """The string at `p.i` (its opening quote): a span of the line, or its unescaped copy in
    `buf` when it has an escape; its UTF-8 checked as Python's codec checks it."""
    cdef const unsigned char* s = p.s
    cdef Py_ssize_t start = p.i + 1, i = p.i + 1
    cdef int k
    cdef bint ascii = True
    while True:
        i = _plain(s, i, p.n)
        if s[i] == 34:
            break
        if s[i] == 92:
            return _unescape(p, out, start, i, ascii)
        if s[i] < 32:  # a control character, or the end of the line
            return _fail(p, _MALFORMED)
        k = _utf8_length(s + i)
        if k == 0:
            return _fail(p, _UTF8)
        ascii = False
        i += k
    out.data = <const char*>(s + start)
    out.size = i - start
    out.ascii = ascii
    p.i = i + 1
    return True


cdef bint _unescape(
        Parser* p, Text* out, Py_ssize_t start, Py_ssize_t i, bint ascii) noexcept nogil:
    """The rest of a string from its first escape at `i`, copied unescaped into `buf`."""
    cdef const unsigned char* s = p.s
    cdef unsigned char* first
    cdef unsigned char* d
    cdef Py_ssize_t run
    cdef int k
    cdef long code
    if p.buf == NULL:
        p.buf = <char*>malloc(p.n)
        if p.buf == NULL:
            return _fail(p, _STEPS)
    first = <unsigned char*>p.buf + p.used
    memcpy(first, s + start, i - start)
    d = first + (i - start)
    while True:
        run = i
        i = _plain(s, i, p.n)
        memcpy(d, s + run, i - run)
        d += i - run
        if s[i] == 34:
            break
        if s[i] == 92:
            k = _escape(s + i, &code)
            if k <= 0:
                return _fail(p, _ESCAPE if k < 0 else _MALFORMED)
            i += k
            ascii &= code < 128
            d += _put_utf8(d, code)
        elif s[i] < 32:
            return _fail(p, _MALFORMED)
        else:
            k = _utf8_length(s + i)
            if k == 0:
                return _fail(p, _UTF8)
            memcpy(d, s + i, k)
            d += k
            i += k
            ascii = False
    out.data = <const char*>first
    out.size = d - first
    out.ascii = ascii
    p.used += d - first
    p.i = i + 1
    return True


cdef int _escape(const unsigned char* e, long* code) noexcept nogil:
    """The escape at `e` (its backslash): its length, with its code point in `code`; 0 when
    it is not an escape of JSON, -1 for a lone surrogate (msgspec's error, declined)."""
    cdef long low
    if _SHORT_ESCAPE[e[1]]:
        code[0] = _SHORT_ESCAPE[e[1]]
        return 2
    if e[1] != 117:  # \u
        return 0
    code[0] = _hex4(e + 2)
    if code[0] < 0:
        return 0
    if 0xDC00 <= code[0] <= 0xDFFF:
        return -1
    if 0xD800 <= code[0] <= 0xDBFF:
        if e[6] != 92 or e[7] != 117:
            return -1
        low = _hex4(e + 8)
        if not 0xDC00 <= low <= 0xDFFF:
            return -1
        code[0] = 0x10000 + ((code[0] - 0xD800) << 10) + (low - 0xDC00)
        return 12
    return 6


cdef inline long _hex4(const unsigned char* h) noexcept nogil:
    """Four hex digits as a number, or -1 (stops at the first other byte: the line's NUL)."""
    if _HEX[h[0]] < 0 or _HEX[h[1]] < 0 or _HEX[h[2]] < 0 or _HEX[h[3]] < 0:
        return -1
    return (_HEX[h[0]] << 12) | (_HEX[h[1]] << 8) | (_HEX[h[2]] << 4) | _HEX[h[3]]


cdef inline int _put_utf8(unsigned char* d, long code) noexcept nogil:
    """`code` written as UTF-8 at `d`: its length."""
    cdef int n = 1 if code < 0x80 else 2 if code < 0x800 else 3 if code < 0x10000 else 4, k
    for k in range(n - 1, 0, -1):  # continuation bytes, six bits each, from the last
        d[k] = <unsigned char>(0x80 | (code & 0x3F))
        code >>= 6
    d[0] = <unsigned char>(code if n == 1 else ((0xFF << (8 - n)) & 0xFF) | code)
    return n


cdef int _utf8_length(const unsigned char* q) noexcept nogil:
    """The length of the UTF-8 character at `q` (a byte >= 0x80), or 0 where Python's codec
    rejects it: a stray continuation byte, an overlong form, a surrogate, past U+10FFFF, a cut
    sequence (the line's closing NUL is no continuation byte, so reading stops there). A
    continuation byte is 10xxxxxx."""
    cdef unsigned char c = q[0], low = 0x80, high = 0xBF
    if c < 0xC2:
        return 0
    if c < 0xE0:
        return 2 if (q[1] & 0xC0) == 0x80 else 0
    if c < 0xF0:
        if c == 0xE0:
            low = 0xA0
        elif c == 0xED:
            high = 0x9F
        return 3 if low <= q[1] <= high and (q[2] & 0xC0) == 0x80 else 0
    if c < 0xF5:
        if c == 0xF0:
            low = 0x90
        elif c == 0xF4:
            high = 0x8F
        return 4 if low <= q[1] <= high and (q[2] & 0xC0) == 0x80 and (q[3] & 0xC0) == 0x80 else 0
    return 0
