# cython: language_level=3, boundscheck=False, wraparound=False, initializedcheck=False
"""The action grammar's common shapes, compiled (PROTOCOL §2).

`parse_ascii` reads an ASCII response and either decides it exactly as the reference parser
(`replay.semantics._parse.parse_action`) would, or answers PARSE_FALLBACK and leaves it to
the reference. It decides: no `Action:` label, several labels, and one label followed by a
call in the canonical shape (the reference's `_FAST` pattern, a known action name, plain or
quoted params). It follows the reference's regular expressions choice by choice (greedy
first, alternatives in order) and gives up wherever they would backtrack, so what it
accepts is what they accept; `tests/replay/kernel` checks it against the reference on
generated texts.
"""

from cpython.conversion cimport PyOS_string_to_double
from libc.math cimport isfinite

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


cdef int _labels(const char* s, Py_ssize_t n, Span* first, Span* second) noexcept:
    """The reference's `_find_labels`: line-start `Action:` labels if any, else labels
    anywhere (not inside a word). Returns how many (the first two are stored)."""
    cdef int n_line = 0, n_any = 0
    cdef Span line0, line1, any0, any1
    cdef Py_ssize_t pos = 0, j, sol
    cdef bint at_line
    while pos + 6 <= n:
        if not _at_nocase(s, n, pos, b"action", 6):
            pos += 1
            continue
        j = pos + 6
        while j < n and _label_decor(s[j]):
            j += 1
        if j < n and s[j] == 58:  # ':'
            sol = pos
            while sol > 0 and s[sol - 1] != 10:
                sol -= 1
            at_line = True
            for k in range(sol, pos):
                if not _line_decor(s[k]):
                    at_line = False
                    break
            if at_line:
                if n_line == 0:
                    line0.start = sol
                    line0.end = j + 1
                elif n_line == 1:
                    line1.start = sol
                    line1.end = j + 1
                n_line += 1
            elif pos == 0 or not (_alpha(s[pos - 1]) or _digit(s[pos - 1]) or s[pos - 1] == 95):
                if n_any == 0:
                    any0.start = pos
                    any0.end = j + 1
                elif n_any == 1:
                    any1.start = pos
                    any1.end = j + 1
                n_any += 1
        pos += 1
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
    while p <= end:
        if p == 0 or s[p - 1] == 10:
            q = p
            while q < end and _line_decor(s[q]):
                q += 1
            if _at_nocase(s, end, q, b"thinking", 8):
                q += 8
                while q < end and _label_decor(s[q]):
                    q += 1
                if q < end and s[q] == 58:
                    return _strip(s, q + 1, end)
        p += 1
    return _strip(s, 0, end)


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
    # The text goes on with a non-number character, where Python's float parser stops too.
    value[0] = PyOS_string_to_double(s + start, &end, NULL)
    if end != s + q:
        return 0
    p[0] = q
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


cdef const char* _NAMES[7]
_NAMES[0] = b"press"
_NAMES[1] = b"rotate"
_NAMES[2] = b"push"
_NAMES[3] = b"pull"
_NAMES[4] = b"grasp"
_NAMES[5] = b"switch_view"
_NAMES[6] = b"timed_wait"
cdef Py_ssize_t _NAME_LEN[7]
_NAME_LEN[:] = [5, 6, 4, 4, 5, 11, 10]


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


cdef int parse_ascii(const char* s, Py_ssize_t n, FastParse* out) except -1:
    """Decide an ASCII response like the reference parser, or answer PARSE_FALLBACK."""
    cdef Span first, second
    cdef int count = _labels(s, n, &first, &second)
    if count == 0:
        out.status = PARSE_NO_ACTION
        out.thinking = _thinking(s, n)
        return 0
    out.thinking = _thinking(s, first.start)
    if count > 1:
        out.status = PARSE_MULTIPLE
        out.action_text = _strip(s, first.end, second.start)
        return 0
    out.status = PARSE_OK if _call(s, n, first.end, out) else PARSE_FALLBACK
    return 0


def parse_fields(str text):
    """What `parse_ascii` decides for `text`, as Python values (for tests): None when it
    leaves the text to the reference parser, else (status, kind, coord, params, action_text,
    thinking) with params as raw words (not normalised)."""
    cdef FastParse out
    cdef bytes data
    cdef const char* s
    if not text.isascii():
        return None
    data = text.encode("ascii")
    s = data
    parse_ascii(s, len(data), &out)
    if out.status == PARSE_FALLBACK:
        return None
    thinking = data[out.thinking.start:out.thinking.end].decode()
    if out.status == PARSE_NO_ACTION:
        return ("no_action", None, None, (), "", thinking)
    action_text = data[out.action_text.start:out.action_text.end].decode()
    if out.status == PARSE_MULTIPLE:
        return ("multiple_actions", None, None, (), action_text, thinking)
    params = tuple(data[out.params[i].start:out.params[i].end].decode() for i in range(out.n_params))
    coord = (out.x, out.y) if out.has_coord else None
    return ("ok", out.kind, coord, params, action_text, thinking)
