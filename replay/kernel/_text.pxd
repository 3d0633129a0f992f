# The compiled action grammar (see _text.pyx).

cdef enum:
    MAX_PARAMS = 8

cdef enum:
    PARSE_FALLBACK = 0   # not decided here: the reference parser decides
    PARSE_OK = 1         # a well-formed call in the canonical shape
    PARSE_NO_ACTION = 2
    PARSE_MULTIPLE = 3
    PARSE_UNKNOWN = 4    # unknown_action
    PARSE_MALFORMED = 5

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
    Span action_text     # the reference's action_text
    int n_params
    Span params[MAX_PARAMS]  # each item's word, quotes removed (normalised by the caller)

cdef int parse_utf8(const char* s, Py_ssize_t n, bint ascii, FastParse* out) except -1
