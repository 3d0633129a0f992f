# A logged step's fields as the kernel reads them, from either source: a msgspec `LogStep`
# (decoded by the record rules' implementation, `replay.semantics.EpisodeLog`) or a line of
# `episodes.jsonl` decoded straight into these structs (`_logline.pyx`, which declines every
# line it cannot prove msgspec would decode to the same values: those go through msgspec).

from cpython.object cimport PyObject
from libc.stdint cimport int64_t


cdef struct Text:
    const char* data      # UTF-8, not NUL-terminated; NULL when absent or JSON null
    Py_ssize_t size
    bint ascii            # every byte below 0x80


cdef enum:
    TS_NONE = 0           # no timestamp (absent, null, or a text timestamp_seconds rejects)
    TS_NUMBER = 1         # `ts`: the seconds, as `timestamp_seconds` gives them
    TS_TEXT = 2           # `ts_text`: a string, for `timestamp_seconds` (an ISO 8601 time)


cdef struct StepIn:
    Text output
    Text view
    Text feedback
    Text state
    int ts_kind
    double ts
    Text ts_text
    bint has_prompt
    bint has_completion
    bint has_latency
    int64_t prompt
    int64_t completion
    double latency
    PyObject* step        # borrowed: the `LogStep` read (msgspec's path), NULL for a decoded line


cdef class LogLine:
    """One episode record decoded straight from its line: `steps[0:n_steps]` point into
    `raw` (strings without escapes) or into `buf` (unescaped copies), both owned here."""
    cdef readonly bytes raw
    cdef readonly str episode_id
    cdef readonly object ended          # None or "context_exceeded"
    cdef StepIn* steps
    cdef Py_ssize_t n_steps
    cdef char* buf
