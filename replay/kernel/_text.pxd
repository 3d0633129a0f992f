# The compiled parser of the common response shapes (see _text.pyx).

cdef enum:
    MAX_PARAMS = 8

cdef enum:
    PARSE_FALLBACK = 0   # not decided here: the reference parser decides
    PARSE_OK = 1         # a well-formed call in the canonical shape
    PARSE_NO_ACTION = 2
    PARSE_MULTIPLE = 3

cdef struct Span:
    Py_ssize_t start
    Py_ssize_t end

cdef struct FastParse:
    int status
    int kind             # action code (ACTION_NAMES order) when PARSE_OK
    bint has_coord
    double x
    double y
    Span thinking        # stripped Thinking text
    Span action_text     # the call (PARSE_OK) or the stripped first entry (PARSE_MULTIPLE)
    int n_params
    Span params[MAX_PARAMS]  # each item's word, quotes removed (normalised by the caller)

cdef int parse_ascii(const char* s, Py_ssize_t n, FastParse* out) except -1
