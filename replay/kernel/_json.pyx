# cython: language_level=3, boundscheck=False, wraparound=False, initializedcheck=False
"""The nesting depth of JSON text, in one pass over its bytes (PROTOCOL §1.5).

The decoder recurses once per level and stops where Python's stack does, which depends on
the caller's depth: a bound checked here first gives every decoding the same verdict,
whatever process or thread runs it."""

from libc.string cimport memchr


def nested_beyond(const unsigned char[::1] data, Py_ssize_t limit):
    """The offset of the first `[` or `{` opening a level deeper than `limit`, or -1.
    Brackets inside strings do not count; the bytes need not be valid JSON (the decoder
    judges the rest). A string is crossed with `memchr` (most of a record is text).

    Most texts have fewer openers in all than `limit` (a record has some tens), so none can
    open a level beyond it: they are counted first, in a loop the C compiler vectorises, and
    the scan that tells strings apart runs only on texts with more."""
    cdef Py_ssize_t i = 0, n = data.shape[0], depth = 0, found = -1, start, k
    cdef const unsigned char* s
    cdef const unsigned char* quote
    cdef unsigned char c
    if n == 0:
        return -1
    s = &data[0]
    if _openers(s, n) <= limit:
        return -1
    with nogil:
        while i < n:
            c = s[i]
            if c == 34:  # a string: to the first quote not escaped by an odd run of backslashes
                start = i + 1
                i = start
                while True:
                    quote = <const unsigned char*>memchr(s + i, 34, n - i)
                    if quote == NULL:
                        i = n
                        break
                    i = quote - s
                    k = i
                    while k > start and s[k - 1] == 92:
                        k -= 1
                    if (i - k) % 2 == 0:
                        break
                    i += 1
            elif c == 91 or c == 123:
                depth += 1
                if depth > limit:
                    found = i
                    break
            elif c == 93 or c == 125:
                depth -= 1
            i += 1
    return found


cdef Py_ssize_t _openers(const unsigned char* s, Py_ssize_t n) noexcept nogil:
    """The number of `[` and `{` bytes in `s`, strings included (a bound on the depth)."""
    cdef Py_ssize_t i, count = 0
    for i in range(n):
        count += (s[i] == 91) | (s[i] == 123)
    return count
