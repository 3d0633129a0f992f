# cython: language_level=3, boundscheck=False, wraparound=False, initializedcheck=False
"""The action grammar, compiled (PROTOCOL §2).

`parse_utf8` reads a response (its UTF-8 bytes) and either decides it exactly as the
reference parser (`replay.semantics._parse.parse_action`) would, or answers PARSE_FALLBACK
and leaves it to the reference. It follows the reference step by step: the labels, the
Thinking text, the canonical call (the reference's `_FAST` pattern, choice by choice:
greedy first, alternatives in order, giving up wherever that pattern would backtrack), then
the full grammar (`_parse_entry_full` and its helpers). Text outside ASCII is read byte by
byte, which agrees with Python's rules except for Unicode whitespace and the four letters
that case-insensitive matching equates with ASCII ones (İ ı ſ K): a response holding one of
those, or a quoted coordinate outside ASCII, is left to the reference. `tests/replay/kernel`
checks the two parsers against each other on generated texts.
"""

from cpython.conversion cimport PyOS_string_to_double
from cpython.unicode cimport Py_UNICODE_ISALNUM, Py_UNICODE_ISSPACE
from libc.string cimport memchr
from libc.math cimport isfinite

from ..semantics import ACTION_NAMES

# Python's str.isspace() and re's \s, restricted to ASCII.
cdef inline bint _space(char c) noexcept:
    return c == 32 or (9 <= c <= 13) or (28 <= c <= 31)

cdef inline char _lower(char c) noexcept:
    return c + 32 if 65 <= c <= 90 else c

cdef inline bint _alpha(char c) noexcept:
    return (65 <= c <= 90) or (97 <= c <= 122)

cdef inline bint _digit(char c) noexcept:
    return 48 <= c <= 57

cdef inline bint _line_decor(char c) noexcept:  # [ \t>*_#`\-]
    return c == 32 or c == 9 or c == 62 or c == 42 or c == 95 or c == 35 or c == 96 or c == 45

cdef inline bint _label_decor(char c) noexcept:  # [ \t*_`]
    return c == 32 or c == 9 or c == 42 or c == 95 or c == 96

cdef inline bint _lang(char c) noexcept:  # [A-Za-z0-9_+-]
    return _alpha(c) or _digit(c) or c == 95 or c == 43 or c == 45

cdef inline bint _word(char c) noexcept:  # [A-Za-z0-9_*.+\-]
    return _alpha(c) or _digit(c) or c == 95 or c == 42 or c == 46 or c == 43 or c == 45

cdef inline bint _params_char(char c) noexcept:  # [A-Za-z0-9_*.+\-'", \t]
    return _word(c) or c == 39 or c == 34 or c == 44 or c == 32 or c == 9


cdef inline bint _at(const char* s, Py_ssize_t n, Py_ssize_t p, const char* lit, Py_ssize_t k) noexcept:
    """s[p:p+k] == lit (case-sensitive)."""
    cdef Py_ssize_t i
    if p + k > n:
        return False
    for i in range(k):
        if s[p + i] != lit[i]:
            return False
    return True


cdef inline bint _at_nocase(const char* s, Py_ssize_t n, Py_ssize_t p, const char* lit, Py_ssize_t k) noexcept:
    """s[p:p+k].lower() == lit (lit lowercase)."""
    cdef Py_ssize_t i
    if p + k > n:
        return False
    for i in range(k):
        if _lower(s[p + i]) != lit[i]:
            return False
    return True


cdef inline Py_ssize_t _skip_space(const char* s, Py_ssize_t n, Py_ssize_t p) noexcept:
    while p < n and _space(s[p]):
        p += 1
    return p


cdef inline Py_ssize_t _skip_blank(const char* s, Py_ssize_t n, Py_ssize_t p) noexcept:  # [ \t]*
    while p < n and (s[p] == 32 or s[p] == 9):
        p += 1
    return p


cdef inline Span _strip(const char* s, Py_ssize_t start, Py_ssize_t end) noexcept:
    cdef Span span
    while start < end and _space(s[start]):
        start += 1
    while end > start and _space(s[end - 1]):
        end -= 1
    span.start = start
    span.end = end
    return span


cdef Py_UCS4 _decode_at(const char* s, Py_ssize_t n, Py_ssize_t p, Py_ssize_t* length) noexcept:
    """The code point of the UTF-8 sequence at p (valid UTF-8: it comes from a str)."""
    cdef unsigned char c = <unsigned char>s[p]
    cdef unsigned int cp
    cdef Py_ssize_t k, count
    if c < 0x80:
        length[0] = 1
        return c
    if c >= 0xF0:
        cp = c & 0x07
        count = 3
    elif c >= 0xE0:
        cp = c & 0x0F
        count = 2
    else:
        cp = c & 0x1F
        count = 1
    for k in range(1, count + 1):
        cp = (cp << 6) | ((<unsigned char>s[p + k]) & 0x3F)
    length[0] = count + 1
    return <Py_UCS4>cp


cdef bint _word_before(const char* s, Py_ssize_t pos) noexcept:
    """Is the character before `pos` a word character (`isalnum()` or `_`, re's `\\w`)?"""
    cdef unsigned char c = <unsigned char>s[pos - 1]
    cdef Py_ssize_t start = pos - 1, length
    if c < 0x80:
        return _alpha(c) or _digit(c) or c == 95
    while start > 0 and (<unsigned char>s[start] & 0xC0) == 0x80:
        start -= 1
    return Py_UNICODE_ISALNUM(_decode_at(s, pos, start, &length))


cdef bint _byte_safe(const char* s, Py_ssize_t n) noexcept:
    """Whether reading the text byte by byte follows Python's rules: no Unicode whitespace
    outside ASCII, and none of the letters İ ı ſ K that case-insensitive matching equates
    with ASCII letters (nor İ, whose lowercase is two characters)."""
    cdef Py_ssize_t p = 0, length
    cdef Py_UCS4 cp
    while p < n:
        if <unsigned char>s[p] < 0x80:
            p += 1
            continue
        cp = _decode_at(s, n, p, &length)
        if Py_UNICODE_ISSPACE(cp) or cp == 0x130 or cp == 0x131 or cp == 0x17F or cp == 0x212A:
            return False
        p += length
    return True


cdef int _labels(const char* s, Py_ssize_t n, Span* first, Span* second) noexcept:
    """The reference's `_find_labels`: line-start `Action:` labels if any, else labels
    anywhere (not inside a word). Returns how many (the first two are stored).

    Found from the colons: a label is "action" (any case), label decoration, then ":", so
    each colon closes at most one label, and colons come in the order of their labels."""
    cdef int n_line = 0, n_any = 0
    cdef Span line0, line1, any0, any1
    cdef Py_ssize_t colon, pos, k, sol = 0, searched = 0, decor_end = -1
    cdef bint at_line
    cdef const char* nl
    cdef const char* hit = <const char*>memchr(s, 58, n)
    while hit != NULL:
        colon = hit - s
        hit = <const char*>memchr(hit + 1, 58, n - colon - 1) if colon + 1 < n else NULL
        k = colon - 1
        while k >= 0 and _label_decor(s[k]):
            k -= 1
        pos = k - 5
        if pos < 0 or not _at_nocase(s, n, pos, b"action", 6):
            continue
        # Labels come in order: the start of each one's line (`sol`) and the end of that
        # line's decoration are found going forward, each byte looked at once (linear time,
        # however many labels a line holds).
        nl = <const char*>memchr(s + searched, 10, pos - searched)
        while nl != NULL:
            sol = nl - s + 1
            decor_end = -1
            nl = <const char*>memchr(s + sol, 10, pos - sol)
        searched = pos
        if decor_end < 0:
            decor_end = sol
            while decor_end < n and _line_decor(s[decor_end]):
                decor_end += 1
        at_line = decor_end >= pos
        if at_line:
            if n_line == 0:
                line0.start = sol
                line0.end = colon + 1
            elif n_line == 1:
                line1.start = sol
                line1.end = colon + 1
            n_line += 1
        elif pos == 0 or not _word_before(s, pos):
            if n_any == 0:
                any0.start = pos
                any0.end = colon + 1
            elif n_any == 1:
                any1.start = pos
                any1.end = colon + 1
            n_any += 1
    if n_line:
        first[0] = line0
        second[0] = line1
        return n_line
    first[0] = any0
    second[0] = any1
    return n_any


cdef Span _thinking(const char* s, Py_ssize_t end) noexcept:
    """The reference's `_thinking`: the text after the first line-start `Thinking:` label
    before `end`, else everything before `end`; stripped."""
    cdef Py_ssize_t p = 0, q
    cdef const char* nl
    while p <= end:
        q = p
        while q < end and _line_decor(s[q]):
            q += 1
        if _at_nocase(s, end, q, b"thinking", 8):
            q += 8
            while q < end and _label_decor(s[q]):
                q += 1
            if q < end and s[q] == 58:
                return _strip(s, q + 1, end)
        if p >= end:
            break
        nl = <const char*>memchr(s + p, 10, end - p)
        if nl == NULL:
            break
        p = nl - s + 1
    return _strip(s, 0, end)


cdef double _POW10[23]
_POW10[0] = 1.0
for _i in range(1, 23):
    _POW10[_i] = _POW10[_i - 1] * 10.0


cdef bint _exact_decimal(const char* s, Py_ssize_t a, Py_ssize_t b, double* value) noexcept:
    """`[-+]?digits[.digits]` in s[a:b] as Python's float() reads it, when the digits fit
    in 2**53 and there are at most 22 after the point: then digits / 10**k is one IEEE
    division of two exact numbers, correctly rounded like the decimal itself."""
    cdef unsigned long long m = 0
    cdef int fraction = -1, count = 0
    cdef bint negative = s[a] == 45
    cdef Py_ssize_t q = a + (s[a] == 43 or s[a] == 45)
    for q in range(q, b):
        if s[q] == 46:
            fraction = 0
            continue
        m = m * 10 + <unsigned long long>(s[q] - 48)
        count += 1
        if fraction >= 0:
            fraction += 1
        if count > 15:
            return False
    value[0] = <double>m / _POW10[fraction] if fraction > 0 else <double>m
    if negative:
        value[0] = -value[0]
    return True


cdef int _number(const char* s, Py_ssize_t n, Py_ssize_t* p, double* value) except -1:
    """NUM of the fast pattern, `[-+]?\\d+(?:\\.\\d+)?`, at p; 0 when it does not match."""
    cdef Py_ssize_t q = p[0], start = p[0]
    cdef char* end
    if q < n and (s[q] == 43 or s[q] == 45):
        q += 1
    if q >= n or not _digit(s[q]):
        return 0
    while q < n and _digit(s[q]):
        q += 1
    if q + 1 < n and s[q] == 46 and _digit(s[q + 1]):
        q += 2
        while q < n and _digit(s[q]):
            q += 1
    p[0] = q
    if not _exact_decimal(s, start, q, value):
        # The text goes on with a non-number character, where Python's float parser stops too.
        value[0] = PyOS_string_to_double(s + start, &end, NULL)
        if end != s + q:
            return 0
    return 1


cdef int _params_list(const char* s, Py_ssize_t n, Py_ssize_t* p, Span* raw) noexcept:
    """PARAMS of the fast pattern at p: `params\\s*=\\s*\\[chars*\\]`."""
    cdef Py_ssize_t q = p[0]
    if not _at(s, n, q, b"params", 6):
        return 0
    q = _skip_space(s, n, q + 6)
    if q >= n or s[q] != 61:  # '='
        return 0
    q = _skip_space(s, n, q + 1)
    if q >= n or s[q] != 91:  # '['
        return 0
    q += 1
    raw.start = q
    while q < n and _params_char(s[q]):
        q += 1
    if q >= n or s[q] != 93:  # ']'
        return 0
    raw.end = q
    p[0] = q + 1
    return 1


cdef int _coord(const char* s, Py_ssize_t n, Py_ssize_t* p, double* x, double* y) except -1:
    """COORD of the fast pattern at p: `coord\\s*=\\s*\\[\\s*NUM\\s*,\\s*NUM\\s*\\]`."""
    cdef Py_ssize_t q = p[0]
    if not _at(s, n, q, b"coord", 5):
        return 0
    q = _skip_space(s, n, q + 5)
    if q >= n or s[q] != 61:
        return 0
    q = _skip_space(s, n, q + 1)
    if q >= n or s[q] != 91:
        return 0
    q = _skip_space(s, n, q + 1)
    if not _number(s, n, &q, x):
        return 0
    q = _skip_space(s, n, q)
    if q >= n or s[q] != 44:  # ','
        return 0
    q = _skip_space(s, n, q + 1)
    if not _number(s, n, &q, y):
        return 0
    q = _skip_space(s, n, q)
    if q >= n or s[q] != 93:
        return 0
    p[0] = q + 1
    return 1


cdef int _items(const char* s, Span raw, FastParse* out) noexcept:
    """The reference's `fast_params` split: items of the params text, each a plain word or a
    quoted one (quotes removed); 0 when an item is anything else (the reference decides)."""
    cdef Py_ssize_t a = raw.start, b, k
    cdef Span item
    cdef int count = 0
    cdef char q
    item = _strip(s, raw.start, raw.end)
    out.n_params = 0
    if item.start == item.end:  # no text, or only whitespace
        return 1
    while True:
        b = a
        while b < raw.end and s[b] != 44:
            b += 1
        item = _strip(s, a, b)
        if item.start == item.end:
            # An empty item is only allowed as the one trailing comma after others.
            if b >= raw.end and count > 0:
                break
            return 0
        if count >= MAX_PARAMS:
            return 0
        q = s[item.start]
        if (q == 39 or q == 34) and item.end - item.start >= 3 and s[item.end - 1] == q:
            item.start += 1
            item.end -= 1
        for k in range(item.start, item.end):
            if not _word(s[k]):
                return 0
        out.params[count] = item
        count += 1
        if b >= raw.end:
            break
        a = b + 1
    out.n_params = count
    return 1


# The action names of the grammar, in ACTION_NAMES order (their codes), as C strings: the
# bytes objects stay alive in _NAME_BYTES for as long as the module.
_NAME_BYTES = tuple(name.encode("ascii") for name in ACTION_NAMES)
assert len(_NAME_BYTES) == 7
cdef const char* _NAMES[7]
cdef Py_ssize_t _NAME_LEN[7]
for _i, _name in enumerate(_NAME_BYTES):
    _NAMES[_i] = _name
    _NAME_LEN[_i] = len(_name)


cdef int _kind(const char* s, Span name) noexcept:
    cdef int k
    for k in range(7):
        if name.end - name.start == _NAME_LEN[k] and _at_nocase(s, name.end, name.start, _NAMES[k], _NAME_LEN[k]):
            return k
    return -1


cdef int _call(const char* s, Py_ssize_t n, Py_ssize_t e, FastParse* out) except -1:
    """The reference's `_FAST` pattern matched from e to the end; 0 when it is not certain."""
    cdef Py_ssize_t p = _skip_space(s, n, e), q, r, c0
    cdef Span name, raw
    cdef bint has_params = False
    cdef int kind
    # Opener: a fence line, a backtick or bold (first alternative that matches here).
    if _at(s, n, p, b"```", 3):
        q = p + 3
        while q < n and _lang(s[q]):
            q += 1
        q = _skip_blank(s, n, q)
        if q < n and s[q] == 10:
            p = q + 1
        else:
            p += 1  # the single-backtick alternative
    elif p < n and s[p] == 96:
        p += 1
    elif _at(s, n, p, b"**", 2):
        p += 2
    p = _skip_blank(s, n, p)
    c0 = p
    while p < n and (_alpha(s[p]) or s[p] == 95):
        p += 1
    if p == c0 or p >= n or s[p] != 40:  # '('
        return 0
    name.start = c0
    name.end = p
    p = _skip_space(s, n, p + 1)
    out.has_coord = False
    if _at(s, n, p, b"coord", 5):
        if not _coord(s, n, &p, &out.x, &out.y):
            return 0
        out.has_coord = True
        r = p
        q = _skip_space(s, n, p)
        if q < n and s[q] == 44:
            q = _skip_space(s, n, q + 1)
            if _params_list(s, n, &q, &raw):
                has_params = True
                r = q
        p = r
    elif _at(s, n, p, b"params", 6):
        if not _params_list(s, n, &p, &raw):
            return 0
        has_params = True
    if out.has_coord or has_params:
        p = _skip_space(s, n, p)
        if p < n and s[p] == 44:
            p = _skip_space(s, n, p + 1)
    if p >= n or s[p] != 41:  # ')'
        return 0
    p += 1
    out.action_text.start = c0
    out.action_text.end = p
    # Closer, then an optional period and trailing whitespace to the end.
    p = _skip_blank(s, n, p)
    if p < n and s[p] == 96:
        p += 1
    elif _at(s, n, p, b"**", 2):
        p += 2
    elif _at(s, n, p, b"\n```", 4):
        p += 4
    p = _skip_blank(s, n, p)
    if p < n and s[p] == 46:
        p += 1
    if _skip_space(s, n, p) != n:
        return 0
    kind = _kind(s, name)
    if kind < 0:
        return 0
    if has_params:
        if not _items(s, raw, out):
            return 0
    else:
        out.n_params = 0
    if out.has_coord and not (isfinite(out.x) and isfinite(out.y)):
        return 0
    out.kind = kind
    return 1


# ------------------------------------------------------------------ the full grammar


cdef inline bint _lead_char(char c) noexcept:  # [\s*_]
    return _space(c) or c == 42 or c == 95


cdef Py_ssize_t _matching_paren(const char* s, Py_ssize_t n, Py_ssize_t open_at) noexcept:
    """The reference's `_matching_paren`: the ")" closing the "(" at `open_at`, or -1."""
    cdef int depth = 0
    cdef char quote = 0, ch
    cdef Py_ssize_t i
    for i in range(open_at, n):
        ch = s[i]
        if quote:
            if ch == quote:
                quote = 0
            continue
        if ch == 39 or ch == 34:
            quote = ch
        elif ch == 40:
            depth += 1
        elif ch == 41:
            depth -= 1
            if depth == 0:
                return i
    return -1


cdef bint _known_call_in(const char* s, Py_ssize_t a, Py_ssize_t b) noexcept:
    """The reference's `_KNOWN_CALL.search` on s[a:b]: a known action name at a word start
    (case-insensitive), directly followed by "("."""
    cdef Py_ssize_t i
    cdef int k
    for i in range(a, b):
        if i > a and _word_before(s, i):
            continue
        for k in range(7):
            if (i + _NAME_LEN[k] < b and s[i + _NAME_LEN[k]] == 40
                    and _at_nocase(s, b, i, _NAMES[k], _NAME_LEN[k])):
                return True
    return False


cdef enum:
    ARGS_OK = 0
    ARGS_MALFORMED = 1
    ARGS_UNSURE = 2   # the reference decides (a quoted number outside ASCII, many params)


cdef int _item(const char* s, Py_ssize_t n, Py_ssize_t* p, Span* item) noexcept:
    """The reference's `_parse_item`: a quoted text (quotes removed) or a plain word."""
    cdef Py_ssize_t q = _skip_space(s, n, p[0]), e
    cdef char ch
    if q >= n:
        return ARGS_MALFORMED
    ch = s[q]
    if ch == 39 or ch == 34:
        e = q + 1
        while e < n and s[e] != ch:
            e += 1
        if e >= n:
            return ARGS_MALFORMED
        item.start = q + 1
        item.end = e
        p[0] = e + 1
        return ARGS_OK
    e = q
    while e < n and _word(s[e]):
        e += 1
    if e == q:
        return ARGS_MALFORMED
    item.start = q
    item.end = e
    p[0] = e
    return ARGS_OK


cdef int _list(const char* s, Py_ssize_t n, Py_ssize_t* p, Span* items, int* count, int cap) noexcept:
    """The reference's `_parse_list`: "[...]" or "(...)" of items, a trailing comma allowed."""
    cdef char closing = 93 if s[p[0]] == 91 else 41
    cdef Py_ssize_t q = _skip_space(s, n, p[0] + 1)
    cdef int status
    count[0] = 0
    if q < n and s[q] == closing:
        p[0] = q + 1
        return ARGS_OK
    while True:
        if count[0] >= cap:
            return ARGS_UNSURE
        status = _item(s, n, &q, &items[count[0]])
        if status != ARGS_OK:
            return status
        count[0] += 1
        q = _skip_space(s, n, q)
        if q >= n:
            return ARGS_MALFORMED
        if s[q] == closing:
            p[0] = q + 1
            return ARGS_OK
        if s[q] != 44:
            return ARGS_MALFORMED
        q = _skip_space(s, n, q + 1)
        if q < n and s[q] == closing:
            p[0] = q + 1
            return ARGS_OK


cdef int _coordinate(const char* s, Span item, double* value) except -1:
    """The reference's `_to_coord` for one item: stripped, a number (`_NUMBER`), finite."""
    cdef Span t = _strip(s, item.start, item.end)
    cdef Py_ssize_t q = t.start, digits = 0
    cdef char* end
    for q in range(t.start, t.end):
        if <unsigned char>s[q] >= 0x80:
            return ARGS_UNSURE  # a digit of another script may be a number there
    q = t.start
    if q < t.end and (s[q] == 43 or s[q] == 45):
        q += 1
    while q < t.end and _digit(s[q]):
        q += 1
        digits += 1
    if q < t.end and s[q] == 46:
        q += 1
        while q < t.end and _digit(s[q]):
            q += 1
            digits += 1
    if digits == 0:
        return ARGS_MALFORMED
    if q < t.end and (s[q] == 101 or s[q] == 69):
        q += 1
        if q < t.end and (s[q] == 43 or s[q] == 45):
            q += 1
        if q >= t.end or not _digit(s[q]):
            return ARGS_MALFORMED
        while q < t.end and _digit(s[q]):
            q += 1
    if q != t.end:
        return ARGS_MALFORMED
    value[0] = PyOS_string_to_double(s + t.start, &end, NULL)
    if end != s + t.end:
        return ARGS_UNSURE
    return ARGS_OK if isfinite(value[0]) else ARGS_MALFORMED


cdef inline bint _key_is(const char* s, Span key, const char* lit, Py_ssize_t k) noexcept:
    return key.end - key.start == k and _at_nocase(s, key.end, key.start, lit, k)


cdef int _args(const char* s, Py_ssize_t a, Py_ssize_t b, FastParse* out) except -1:
    """The reference's `_parse_args` on s[a:b]: `key=value` pairs, coord and params once each."""
    cdef Py_ssize_t p = _skip_space(s, b, a)
    cdef Span key
    cdef Span items[MAX_PARAMS]
    cdef int count, status, slot
    cdef bint seen_coord = False, seen_params = False
    out.has_coord = False
    out.n_params = 0
    while p < b:
        key.start = p
        while p < b and (_alpha(s[p]) or s[p] == 95):
            p += 1
        key.end = p
        if key.end == key.start:
            return ARGS_MALFORMED
        p = _skip_space(s, b, p)
        if p >= b or s[p] != 61:
            return ARGS_MALFORMED
        p = _skip_space(s, b, p + 1)
        if (_key_is(s, key, b"coord", 5) or _key_is(s, key, b"coords", 6)
                or _key_is(s, key, b"coordinate", 10) or _key_is(s, key, b"coordinates", 11)):
            slot = 0
            if seen_coord:
                return ARGS_MALFORMED
            seen_coord = True
        elif (_key_is(s, key, b"params", 6) or _key_is(s, key, b"param", 5)
                or _key_is(s, key, b"parameters", 10) or _key_is(s, key, b"parameter", 9)):
            slot = 1
            if seen_params:
                return ARGS_MALFORMED
            seen_params = True
        else:
            return ARGS_MALFORMED
        if p < b and (s[p] == 91 or s[p] == 40):
            status = _list(s, b, &p, items, &count, MAX_PARAMS)
        elif slot == 1:
            status = _item(s, b, &p, &items[0])
            count = 1
        else:
            return ARGS_MALFORMED
        if status != ARGS_OK:
            return status
        if slot == 0:
            if count != 2:
                return ARGS_MALFORMED
            status = _coordinate(s, items[0], &out.x)
            if status == ARGS_OK:
                status = _coordinate(s, items[1], &out.y)
            if status != ARGS_OK:
                return status
            out.has_coord = True
        else:
            for k in range(count):
                out.params[k] = items[k]
            out.n_params = count
        p = _skip_space(s, b, p)
        if p < b:
            if s[p] != 44:
                return ARGS_MALFORMED
            p = _skip_space(s, b, p + 1)
    return ARGS_OK


cdef int _full(const char* s, Py_ssize_t n, Py_ssize_t e, FastParse* out) except -1:
    """The reference's `_parse_entry_full` on s[e:]: sets out.status (PARSE_FALLBACK when
    unsure) and out.action_text."""
    cdef Py_ssize_t p = e, q, name_end, open_at, close
    cdef int kind, status
    cdef Span name
    # _LEAD: [\s*_]* then a fence line or a fence, then [\s*_`]*
    while p < n and _lead_char(s[p]):
        p += 1
    if _at(s, n, p, b"```", 3):
        q = p + 3
        while q < n and _lang(s[q]):
            q += 1
        q = _skip_blank(s, n, q)
        p = q + 1 if q < n and s[q] == 10 else p + 3
    while p < n and (_lead_char(s[p]) or s[p] == 96):
        p += 1
    out.action_text = _strip(s, e, n)  # "shown"
    # _NAME: [A-Za-z_][A-Za-z0-9_]* \s* (
    if p >= n or not (_alpha(s[p]) or s[p] == 95):
        out.status = PARSE_MALFORMED
        return 0
    name_end = p + 1
    while name_end < n and (_alpha(s[name_end]) or _digit(s[name_end]) or s[name_end] == 95):
        name_end += 1
    open_at = _skip_space(s, n, name_end)
    if open_at >= n or s[open_at] != 40:
        out.status = PARSE_MALFORMED
        return 0
    name.start = p
    name.end = name_end
    kind = _kind(s, name)
    close = _matching_paren(s, n, open_at)
    if close < 0:
        out.status = PARSE_MALFORMED if kind >= 0 else PARSE_UNKNOWN
        return 0
    if _known_call_in(s, close + 1, n):
        out.status = PARSE_MULTIPLE
        return 0
    out.action_text.start = p
    out.action_text.end = close + 1
    if kind < 0:
        out.status = PARSE_UNKNOWN
        return 0
    status = _args(s, open_at + 1, close, out)
    if status == ARGS_UNSURE:
        out.status = PARSE_FALLBACK
    elif status == ARGS_MALFORMED:
        out.status = PARSE_MALFORMED
    else:
        out.status = PARSE_OK
        out.kind = kind
    return 0


cdef int parse_utf8(const char* s, Py_ssize_t n, bint ascii, FastParse* out) except -1:
    """Decide a response (its UTF-8 bytes) like the reference parser, or answer
    PARSE_FALLBACK; `ascii` says the text is known to be ASCII."""
    cdef Span first, second
    cdef int count
    if not ascii and not _byte_safe(s, n):
        out.status = PARSE_FALLBACK
        return 0
    count = _labels(s, n, &first, &second)
    if count == 0:
        out.status = PARSE_NO_ACTION
        out.thinking = _thinking(s, n)
        return 0
    out.thinking = _thinking(s, first.start)
    if count > 1:
        out.status = PARSE_MULTIPLE
        out.action_text = _strip(s, first.end, second.start)
        return 0
    if _call(s, n, first.end, out):
        out.status = PARSE_OK
    else:
        _full(s, n, first.end, out)
    return 0


def parse_fields(str text):
    """What `parse_utf8` decides for `text`, as Python values (for tests): None when it
    leaves the text to the reference parser, else (status, kind, coord, params, action_text,
    thinking) with params as raw items (not normalised)."""
    cdef FastParse out
    cdef bytes data = text.encode("utf-8", "surrogatepass")
    cdef const char* s = data
    parse_utf8(s, len(data), text.isascii(), &out)
    if out.status == PARSE_FALLBACK:
        return None
    thinking = data[out.thinking.start:out.thinking.end].decode()
    if out.status == PARSE_NO_ACTION:
        return ("no_action", None, None, (), "", thinking)
    action_text = data[out.action_text.start:out.action_text.end].decode()
    if out.status != PARSE_OK:
        detail = {PARSE_MULTIPLE: "multiple_actions", PARSE_UNKNOWN: "unknown_action"}
        return (detail.get(out.status, "malformed"), None, None, (), action_text, thinking)
    params = tuple(data[out.params[i].start:out.params[i].end].decode() for i in range(out.n_params))
    coord = (out.x, out.y) if out.has_coord else None
    return ("ok", out.kind, coord, params, action_text, thinking)
