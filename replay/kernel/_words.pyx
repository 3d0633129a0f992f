# cython: language_level=3, boundscheck=False, wraparound=False, initializedcheck=False
"""Code columns to Arrow string buffers: one copy per row from a vocabulary's UTF-8 bytes."""

from cpython.unicode cimport PyUnicode_AsUTF8AndSize
from libc.stdlib cimport free, malloc, realloc
from libc.string cimport memcpy, memset

import numpy as np

cdef enum:
    SHORT = 16  # words this long or shorter are copied as one fixed-size block


cdef class Words:
    """A vocabulary as one UTF-8 buffer with offsets: code columns expand into the buffers of
    a string column with one copy per row (an Arrow `take` of the same costs 1.6 times more).

    The buffer is followed by SHORT spare bytes, so that a short word is copied as a block
    of SHORT bytes, a copy the C compiler makes with two moves instead of a call (most words
    are short: views, states, ids); the bytes past the word land in the spare bytes of the
    column, which are cut off."""

    cdef char* data
    cdef long long* offsets
    cdef readonly Py_ssize_t size

    def __cinit__(self, words):
        cdef Py_ssize_t i, n, cap = 256, used = 0
        cdef const char* s
        cdef char* grown
        items = words if type(words) is list or type(words) is tuple else list(words)
        self.size = len(items)
        self.offsets = <long long*>malloc((self.size + 1) * sizeof(long long))
        self.data = <char*>malloc(cap + SHORT)
        if self.offsets == NULL or self.data == NULL:
            raise MemoryError()
        self.offsets[0] = 0
        for i in range(self.size):
            s = PyUnicode_AsUTF8AndSize(items[i], &n)  # str.encode("utf-8")'s bytes and errors
            if used + n > cap:
                while used + n > cap:
                    cap *= 2
                grown = <char*>realloc(self.data, cap + SHORT)
                if grown == NULL:
                    raise MemoryError()
                self.data = grown
            memcpy(self.data + used, s, n)
            used += n
            self.offsets[i + 1] = used
        memset(self.data + used, 0, SHORT)

    def __dealloc__(self):
        free(self.data)
        free(self.offsets)

    def expand(self, const int[::1] codes, const unsigned char[::1] ok):
        """(UTF-8 data, int32 offsets) of the column whose row i is word `codes[i]` where
        `ok[i]`, and empty (null) elsewhere."""
        cdef Py_ssize_t n = codes.shape[0], i
        cdef const long long* off = self.offsets
        cdef const char* src = self.data
        offsets = np.empty(n + 1, np.int32)
        cdef int[::1] out_off = offsets
        cdef long long total = 0, length
        cdef int c
        out_off[0] = 0
        for i in range(n):
            if ok[i]:
                c = codes[i]
                total += off[c + 1] - off[c]
                if total > 0x7FFFFFFF:
                    raise OverflowError("string column over 2 GiB in one batch")
            out_off[i + 1] = <int>total
        data = np.empty(total + SHORT, np.uint8)
        cdef char* dst = _data(data)
        for i in range(n):
            if ok[i]:
                c = codes[i]
                length = off[c + 1] - off[c]
                if length <= SHORT:
                    memcpy(dst, src + off[c], SHORT)
                else:
                    memcpy(dst, src + off[c], length)
                dst += length
        return data[:total], offsets


cdef char* _data(object array):
    cdef unsigned char[::1] view = array
    return <char*>&view[0]
