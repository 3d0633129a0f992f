# cython: language_level=3, boundscheck=False, wraparound=False, initializedcheck=False
"""Episode records decoded straight into the kernel's step structs (see _logline.pxd).

INTERFACE BASE ONLY (branch iface): the decoder declines every line, so every line goes
through msgspec. The decoder is built on a branch of its own."""

from libc.stdlib cimport free


cdef class LogLine:
    def __dealloc__(self):
        free(self.steps)
        free(self.buf)

    @property
    def continuation(self):
        return None  # a line with a continuation is declined (msgspec decodes it)

    def __len__(self):
        return self.n_steps


def decode_line(bytes raw):
    """The line as a `LogLine`, or None: msgspec decodes it (every doubt is a None)."""
    return None
