# cython: language_level=3, boundscheck=False, wraparound=False, initializedcheck=False, cdivision=True
"""The compiled replay of a batch of episodes: parse, simulate, classify, into column buffers.

Each rule here restates one of the reference engine (`replay.semantics`: `_step.step`,
`_episode.replay_episode`, `_classify.Classifier`) over integer-coded machines
(`KMachine`, `KGoal`); rare situations call the reference functions themselves (responses
the compiled parser leaves open, structured actions, C_opt_dyn). `tests/replay/kernel` proves the tables byte-identical to the
reference's. Strings become codes into per-batch vocabularies (`Vocab`) or are copied into
`TextVec` buffers; `_assemble.py` turns the buffers into Arrow tables.
"""

cimport cython
from cpython.buffer cimport PyBuffer_FillInfo
from cpython.ref cimport Py_INCREF
from cpython.tuple cimport PyTuple_New, PyTuple_SET_ITEM
from cpython.unicode cimport PyUnicode_AsUTF8AndSize, PyUnicode_DecodeUTF8
from libc.math cimport floor, isfinite, pow
from libc.stdlib cimport free, malloc, realloc
from libc.string cimport memcmp, memcpy, memmove, memset

import math

import numpy as np

from ..semantics import (
    ACTION_NAMES,
    DASHBOARD,
    ERROR_DETAILS,
    ERROR_TYPES,
    FB_NULL,
    FEEDBACK_KINDS,
    FRONT,
    NULL_TEXT,
    OPERATIONAL_TEXT,
    ORTHOGRAPHIC_VIEWS,
    SCALE,
    SWITCH_VIEW,
    TERMINATIONS,
    TIMED_WAIT,
    UNLOCKED_TEXT,
    VIEW_ORDER,
    WAIT_NO_EFFECT_TEXT,
    LogStep,
    SimState,
    apply_transition,
    c_opt_dynamic,
    distances,
    invalid_text,
    normalize_param,
    parse_action,
    parse_log_step,
    switched_text,
    target_components,
    timestamp_seconds,
)

from ._logline cimport TS_NONE, TS_NUMBER, TS_TEXT, LogLine, StepIn, Text
from ._text cimport (
    PARSE_FALLBACK,
    PARSE_MALFORMED,
    PARSE_MULTIPLE,
    PARSE_NO_ACTION,
    PARSE_OK,
    PARSE_UNKNOWN,
    FastParse,
    parse_utf8,
)


cdef extern from "Python.h":
    bint PyUnicode_IS_ASCII(object text)
    ctypedef struct PyObject
    ctypedef struct PyMemberDef:
        Py_ssize_t offset
    ctypedef struct PyMemberDescrObject:
        PyMemberDef* d_member

# A logged step's fields, read from their slots: `LogStep` is a msgspec struct, whose fields
# are member descriptors; `getattr` looks each one up in the type's dictionary (a tenth of
# the kernel's time for the eight fields of every step). Anything not exactly a `LogStep`
# (a subclass, a stand-in) is read with `getattr`.
cdef enum:
    F_OUTPUT, F_VIEW, F_FEEDBACK, F_STATE, F_TIMESTAMP, F_PROMPT, F_COMPLETION, F_LATENCY, NF

_STEP_FIELDS = (
    "output", "view", "feedback", "state", "timestamp", "prompt_tokens", "completion_tokens",
    "latency_seconds",
)
cdef Py_ssize_t[NF] _STEP_OFFSET
for _f in range(NF):
    _descr = LogStep.__dict__[_STEP_FIELDS[_f]]
    if type(_descr).__name__ != "member_descriptor":
        raise TypeError(f"LogStep.{_STEP_FIELDS[_f]} is not a slot")
    _STEP_OFFSET[_f] = (<PyMemberDescrObject*>_descr).d_member.offset


cdef object _LOG_STEP = LogStep  # a C global: no look-up in the module's names per field


cdef inline object _step_field(object step, int f, list hold):
    """`getattr(step, <field f>)`, from the slot when `step` is a `LogStep` (which holds the
    value); anything else's is kept in `hold` (a stand-in may make the value anew on each
    read, and its UTF-8 must outlive the read)."""
    cdef PyObject* value
    if type(step) is _LOG_STEP:
        value = (<PyObject**>(<char*><PyObject*>step + _STEP_OFFSET[f]))[0]
        if value != NULL:
            return <object>value
    got = getattr(step, _STEP_FIELDS[f])
    hold.append(got)
    return got


cdef inline int _text_of(object text, Text* t) except -1:
    """`t` spans the UTF-8 of `text` (a str, whose UTF-8 CPython keeps with it), or is
    absent (NULL) for None."""
    if text is None:
        t.data = NULL
        t.size = 0
        t.ascii = True
        return 0
    t.data = PyUnicode_AsUTF8AndSize(text, &t.size)  # TypeError for anything but a str
    t.ascii = PyUnicode_IS_ASCII(text)
    return 0


cdef int _step_in(object step, StepIn* si, list hold) except -1:
    """`si` filled from a `LogStep` (msgspec's path), which it borrows (`si.step`): its texts
    as UTF-8 spans into its strings, a float timestamp as seconds, an ASCII str one as its
    text (`timestamp_seconds` reads it where it is used), any other through
    `timestamp_seconds` now (a str msgspec did not make may have no UTF-8: a lone surrogate
    is no time, not an error); its counts and latency converted as the columns hold them."""
    cdef double seconds
    si.step = <PyObject*>step
    _text_of(_step_field(step, F_OUTPUT, hold), &si.output)
    _text_of(_step_field(step, F_VIEW, hold), &si.view)
    _text_of(_step_field(step, F_FEEDBACK, hold), &si.feedback)
    _text_of(_step_field(step, F_STATE, hold), &si.state)
    ts = _step_field(step, F_TIMESTAMP, hold)
    si.ts_kind = TS_NONE
    if type(ts) is float:
        si.ts_kind = TS_NUMBER
        si.ts = ts
    elif type(ts) is str and PyUnicode_IS_ASCII(ts):
        si.ts_kind = TS_TEXT
        _text_of(ts, &si.ts_text)
    elif ts is not None:
        ts = timestamp_seconds(ts)
        if ts is not None:
            si.ts_kind = TS_NUMBER
            si.ts = ts
    value = _step_field(step, F_PROMPT, hold)
    si.has_prompt = value is not None
    if si.has_prompt:
        si.prompt = value
    value = _step_field(step, F_COMPLETION, hold)
    si.has_completion = value is not None
    if si.has_completion:
        si.completion = value
    value = _step_field(step, F_LATENCY, hold)
    si.has_latency = value is not None
    if si.has_latency:
        seconds = value
        si.latency = seconds
    return 0


cdef inline bint _same(const Text* a, const Text* b) noexcept:
    """Two present texts hold the same bytes (equal UTF-8 <=> equal str)."""
    return (
        b.data != NULL and a.size == b.size
        and (a.size == 0 or memcmp(a.data, b.data, a.size) == 0)
    )


cdef inline str _decoded(const Text* t):
    """The str of a present text (valid UTF-8: the str it was encoded from)."""
    return PyUnicode_DecodeUTF8(t.data, t.size, NULL)


@cython.final
cdef class Names:
    """Strings (or None) with their UTF-8 at hand, for comparisons with what a log recorded:
    `at[i]` spans the UTF-8 of the i-th, which CPython keeps with the str (held here)."""

    cdef readonly list strs
    cdef Text* at
    cdef Py_ssize_t n, cap

    def __cinit__(self, strs=()):
        self.strs = []
        self.n = self.cap = 0
        self.at = NULL
        self.extend(strs)

    def __dealloc__(self):
        free(self.at)

    cdef int extend(self, object strs) except -1:
        cdef Py_ssize_t cap
        cdef Text* at
        for text in strs:
            if self.n == self.cap:
                cap = self.cap * 2 if self.cap else 16
                at = <Text*>realloc(self.at, cap * sizeof(Text))
                if at == NULL:
                    raise MemoryError()
                self.at = at
                self.cap = cap
            _text_of(text, &self.at[self.n])
            self.strs.append(text)
            self.n += 1
        return 0

# ------------------------------------------------------------------------------ codes

cdef enum:
    NV = 9            # views, in VIEW_ORDER
    V_DASHBOARD = 6
    A_SWITCH = 5      # actions, in ACTION_NAMES
    A_WAIT = 6
    K_INVALID = 0     # feedback kinds, in FEEDBACK_KINDS
    K_SWITCHED = 1
    K_TRANSITION = 2
    K_WAIT_NO_EFFECT = 3
    K_UNLOCKED = 4
    K_OPERATIONAL = 5
    K_NULL = 6
    E_INVALID_COORD = 0   # error types, in ERROR_TYPES
    E_COMPONENT = 1
    E_PARAMS = 2
    E_ACTION = 3
    E_WAITING = 4
    E_SWITCH_NN = 5
    E_SWITCH_PN = 6
    SC_NP = 0         # switch classes, in SWITCH_CLASSES
    SC_PN = 1
    SC_NN = 2
    SC_PP = 3

assert VIEW_ORDER.index(DASHBOARD) == V_DASHBOARD and len(VIEW_ORDER) == NV
assert ACTION_NAMES.index(SWITCH_VIEW) == A_SWITCH and ACTION_NAMES.index(TIMED_WAIT) == A_WAIT
assert FEEDBACK_KINDS[K_NULL] == FB_NULL and ERROR_TYPES[E_SWITCH_PN] == "switch_view_pn"

cdef double _SCALE = SCALE  # the coordinate scale (PROTOCOL §1.2), from the semantics

VIEW_CODE = {v: i for i, v in enumerate(VIEW_ORDER)}
ACTION_CODE = {a: i for i, a in enumerate(ACTION_NAMES)}
DETAILS = ERROR_DETAILS
"""Every detail code (parse failures, invalid actions, wrong_action, no_effect)."""
DETAIL_CODE = {d: i for i, d in enumerate(DETAILS)}
cdef int D_WRONG_ACTION = DETAIL_CODE["wrong_action"]
cdef int D_UNKNOWN = DETAIL_CODE["unknown_action"]
cdef int D_NO_EFFECT = DETAIL_CODE["no_effect"]
cdef int D_OUT_OF_RANGE = DETAIL_CODE["out_of_range"]
cdef int D_MALFORMED = DETAIL_CODE["malformed"]
cdef int D_NO_ACTION = DETAIL_CODE["no_action"]
cdef int D_MULTIPLE = DETAIL_CODE["multiple_actions"]
cdef int D_AXONOMETRIC = DETAIL_CODE["axonometric_view"]
cdef int D_MISSING_COORD = DETAIL_CODE["missing_coord"]
cdef int D_INVALID_VIEW = DETAIL_CODE["invalid_view"]
cdef int D_LOCKED = DETAIL_CODE["locked_dashboard"]
cdef int[6] _STATUS_DETAIL
_STATUS_DETAIL[:] = [-1, -1, D_NO_ACTION, D_MULTIPLE, D_UNKNOWN, D_MALFORMED]

cdef unsigned int INTERACTABLE = 0
for _v in ORTHOGRAPHIC_VIEWS + (DASHBOARD,):
    INTERACTABLE |= 1 << <int>VIEW_CODE[_v]

# Feedback texts that do not depend on the device, first in every batch's text vocabulary:
# the invalid-action texts by detail code, the switch texts by view, then four fixed ones.
FIXED_TEXTS = (
    [invalid_text(d) for d in DETAILS]
    + [switched_text(v, False) for v in VIEW_ORDER]
    + [switched_text(DASHBOARD, True), OPERATIONAL_TEXT, NULL_TEXT, WAIT_NO_EFFECT_TEXT, UNLOCKED_TEXT]
)
cdef int T_SWITCHED = len(DETAILS)
cdef int T_UNLOCK_SWITCH = T_SWITCHED + NV
cdef int T_OPERATIONAL = T_UNLOCK_SWITCH + 1
cdef int T_NULL = T_UNLOCK_SWITCH + 2
cdef int T_WAIT_NO_EFFECT = T_UNLOCK_SWITCH + 3
cdef int T_UNLOCKED = T_UNLOCK_SWITCH + 4
N_FIXED_TEXTS = len(FIXED_TEXTS)


# ------------------------------------------------------------------------------ buffers


cdef class IntVec:
    """A growable int32 array. Its values are handed to numpy and Arrow without a copy (the
    buffer protocol); it cannot grow while they are."""

    cdef int* data
    cdef Py_ssize_t size, cap
    cdef int exports

    def __cinit__(self, Py_ssize_t cap=64):
        self.cap = cap if cap > 0 else 1
        self.data = <int*>malloc(self.cap * sizeof(int))
        self.size = 0
        if self.data == NULL:
            raise MemoryError()

    def __dealloc__(self):
        free(self.data)

    cdef inline int push(self, int value) except -1:
        if self.size == self.cap:
            self._grow(self.size + 1)
        self.data[self.size] = value
        self.size += 1
        return 0

    cdef int _grow(self, Py_ssize_t need) except -1:
        cdef Py_ssize_t cap = self.cap
        if self.exports:
            raise BufferError("an IntVec cannot grow while its values are in use")
        while cap < need:
            cap *= 2
        cdef int* data = <int*>realloc(self.data, cap * sizeof(int))
        if data == NULL:
            raise MemoryError()
        self.data = data
        self.cap = cap
        return 0

    def __getbuffer__(self, Py_buffer* view, int flags):
        PyBuffer_FillInfo(view, self, self.data, self.size * sizeof(int), 1, flags)
        self.exports += 1

    def __releasebuffer__(self, Py_buffer* view):
        self.exports -= 1

    def array(self):
        """The values as a read-only int32 array over this vector's memory."""
        return np.frombuffer(self, np.int32)


cdef class TextVec:
    """A growable column of strings (UTF-8 bytes, int32 offsets, validity). Its bytes are
    handed to Arrow without a copy (some 16 MB a batch, and the pages a copy would fault
    in); it cannot grow while they are in use."""

    cdef char* data
    cdef Py_ssize_t nbytes, cap
    cdef int exports
    cdef IntVec offsets
    cdef IntVec valid

    def __cinit__(self, Py_ssize_t cap=4096):
        self.cap = cap if cap > 0 else 1
        self.data = <char*>malloc(self.cap)
        self.nbytes = 0
        if self.data == NULL:
            raise MemoryError()
        self.offsets = IntVec(1024)
        self.valid = IntVec(1024)
        self.offsets.push(0)

    def __dealloc__(self):
        free(self.data)

    cdef int push_bytes(self, const char* s, Py_ssize_t n) except -1:
        cdef Py_ssize_t cap
        cdef char* data
        if self.nbytes + n > self.cap:
            if self.exports:
                raise BufferError("a TextVec cannot grow while its bytes are in use")
            cap = self.cap
            while cap < self.nbytes + n:
                cap *= 2
            data = <char*>realloc(self.data, cap)
            if data == NULL:
                raise MemoryError()
            self.data = data
            self.cap = cap
        if n:
            memcpy(self.data + self.nbytes, s, n)
        self.nbytes += n
        if self.nbytes > 0x7FFFFFFF:
            raise OverflowError("more than 2 GiB of text in one batch")
        self.offsets.push(<int>self.nbytes)
        self.valid.push(1)
        return 0

    cdef int push_str(self, str text) except -1:
        cdef Py_ssize_t n
        cdef const char* s = PyUnicode_AsUTF8AndSize(text, &n)
        return self.push_bytes(s, n)

    cdef inline int push_text(self, const Text* text) except -1:
        """A recorded text's bytes, or null when it is absent."""
        if text.data == NULL:
            return self.push_null()
        return self.push_bytes(text.data, text.size)

    cdef int push_null(self) except -1:
        self.offsets.push(<int>self.nbytes)
        self.valid.push(0)
        return 0

    def __getbuffer__(self, Py_buffer* view, int flags):
        PyBuffer_FillInfo(view, self, self.data, self.nbytes, 1, flags)
        self.exports += 1

    def __releasebuffer__(self, Py_buffer* view):
        self.exports -= 1

    def buffers(self):
        """(the bytes, int32 offsets, validity as int32 0 or 1) of what was pushed, each
        over this vector's own memory."""
        return memoryview(self), self.offsets.array(), self.valid.array()


cdef struct RepKey:
    # A step's repetition key (`Classifier._repeated`: goal index, state, action, where,
    # params, view), every part a number: the action and view by code, the params by their
    # number in the batch (`Episode._params_id`), where it acted as the sorted components
    # hit (`where` 1, in `Repeats.hits`) or its grid cell (`where` 2; floor() as a double
    # names the int `math.floor` gives, one to one), or nowhere (`where` 0).
    int goal_index, s0, kind, v0, where, params, hits_at, n_hits
    int slot            # where it sits in `Repeats.slots`
    double gx, gy
    unsigned long long hash


cdef inline unsigned long long _mix(unsigned long long h, unsigned long long v) noexcept:
    h ^= v + 0x9E3779B97F4A7C15ULL + (h << 6) + (h >> 2)
    return h * 0xFF51AFD7ED558CCDULL


cdef class Repeats:
    """The repetition keys an episode has met, as a C hash set: what the reference keeps as
    a set of tuples, without a tuple and a set entry per step. Keys are compared in full,
    so the decisions are the set's. Kept for the batch, emptied for each episode."""

    cdef RepKey* keys
    cdef Py_ssize_t n, cap
    cdef int* slots       # open addressing: a key's number, or -1; `mask + 1` of them
    cdef Py_ssize_t mask
    cdef IntVec hits

    def __cinit__(self):
        self.cap = 64
        self.mask = 127
        self.n = 0
        self.keys = <RepKey*>malloc(self.cap * sizeof(RepKey))
        self.slots = <int*>malloc((self.mask + 1) * sizeof(int))
        if self.keys == NULL or self.slots == NULL:
            raise MemoryError()
        memset(self.slots, 0xFF, (self.mask + 1) * sizeof(int))
        self.hits = IntVec(64)

    def __dealloc__(self):
        free(self.keys)
        free(self.slots)

    cdef void clear(self) noexcept:
        cdef Py_ssize_t i
        for i in range(self.n):
            self.slots[self.keys[i].slot] = -1
        self.n = 0
        self.hits.size = 0

    cdef inline Py_ssize_t _slot(self, RepKey* key) noexcept:
        """The slot holding `key`, or the empty one where it would go."""
        cdef Py_ssize_t at = <Py_ssize_t>(key.hash & <unsigned long long>self.mask)
        cdef RepKey* other
        while self.slots[at] >= 0:
            other = &self.keys[self.slots[at]]
            if (
                other.hash == key.hash and other.goal_index == key.goal_index
                and other.s0 == key.s0 and other.kind == key.kind and other.v0 == key.v0
                and other.where == key.where and other.params == key.params
                and other.gx == key.gx and other.gy == key.gy and other.n_hits == key.n_hits
                and memcmp(self.hits.data + other.hits_at, self.hits.data + key.hits_at,
                           key.n_hits * sizeof(int)) == 0
            ):
                return at
            at = (at + 1) & self.mask
        return at

    cdef bint seen(self, RepKey* key, const int* hits) except -1:
        """Whether `key` (with the `key.n_hits` components `hits`) was met before; it is
        remembered from now on."""
        cdef Py_ssize_t i, at
        key.hits_at = <int>self.hits.size
        key.hash = _mix(_mix(_mix(_mix(0, key.goal_index), key.s0), key.kind), key.v0)
        key.hash = _mix(_mix(_mix(key.hash, key.where), key.params), key.n_hits)
        key.hash = _mix(_mix(key.hash, _bits(key.gx)), _bits(key.gy))
        for i in range(key.n_hits):
            key.hash = _mix(key.hash, hits[i])
            self.hits.push(hits[i])  # taken back below when the key is known
        at = self._slot(key)
        if self.slots[at] >= 0:
            self.hits.size = key.hits_at
            return True
        if self.n == self.cap:
            self._grow()
            at = self._slot(key)
        key.slot = <int>at
        self.keys[self.n] = key[0]
        self.slots[at] = <int>self.n
        self.n += 1
        return False

    cdef int _grow(self) except -1:
        """Twice the keys, and the slots rebuilt at four times the keys."""
        cdef Py_ssize_t i, cap = self.cap * 2, mask = cap * 4 - 1
        cdef RepKey* keys = <RepKey*>realloc(self.keys, cap * sizeof(RepKey))
        if keys == NULL:
            raise MemoryError()
        self.keys = keys
        self.cap = cap
        cdef int* slots = <int*>realloc(self.slots, (mask + 1) * sizeof(int))
        if slots == NULL:
            raise MemoryError()
        self.slots = slots
        self.mask = mask
        memset(self.slots, 0xFF, (mask + 1) * sizeof(int))
        for i in range(self.n):
            self.keys[i].slot = <int>self._slot(&self.keys[i])
            self.slots[self.keys[i].slot] = <int>i
        return 0


cdef inline unsigned long long _bits(double value) noexcept:
    cdef unsigned long long bits
    if value == 0.0:
        value = 0.0  # -0.0 and 0.0 are one cell
    memcpy(&bits, &value, sizeof(double))
    return bits


# ------------------------------------------------------------------------------ machines


cdef inline int _ptr_check(object arr) except -1:
    if arr.size == 0:
        raise ValueError("empty table")
    return 0


cdef class KMachine:
    """A compiled machine's tables as flat arrays (built once per machine and process)."""

    cdef readonly object machine
    cdef readonly tuple state_names
    cdef Names state_utf8             # `state_names`, for comparisons with recorded states
    cdef readonly tuple comp_names
    cdef readonly list texts          # feedback text per transition
    cdef dict comp_id
    cdef int n_states, n_comps, n_tr
    cdef unsigned int offered
    cdef bint has_dashboard
    cdef list _keep
    cdef int* reg_off
    cdef double* reg
    cdef int* cr_off
    cdef int* cr_comp
    cdef double* cr
    cdef int* sv_off
    cdef int* cand_tr
    cdef int* cand_roff
    cdef double* cand_rect
    cdef int* tr_action
    cdef int* tr_comp
    cdef int* tr_index
    cdef int* tr_end
    cdef int* tr_ent_off
    cdef int* tr_ent
    cdef unsigned char* tr_dangerous
    cdef list tr_params
    cdef int* wait_tr
    cdef dict goals
    cdef dict dyn_memo

    def __init__(self, machine):
        self.machine = machine
        self.state_names = tuple(machine.states)
        self.state_utf8 = Names(self.state_names)
        self.n_states = len(self.state_names)
        self.comp_names = tuple(sorted({t.component for t in machine.transitions if t.action is not None}))
        self.n_comps = len(self.comp_names)
        self.comp_id = {c: i for i, c in enumerate(self.comp_names)}
        self.offered = 0
        for view in machine.views:
            self.offered |= 1 << <int>VIEW_CODE[view]
        self.has_dashboard = bool(machine.dashboard_regions)
        self._keep = []
        self.goals = {}
        self.dyn_memo = {}
        self._view_tables(machine)
        tr_id = self._transition_tables(machine)
        self._candidate_tables(machine, tr_id)

    cdef int _view_tables(self, object machine) except -1:
        """Per view: the dashboard regions, and the components' boxes (for the hits)."""
        cdef int v
        reg_off = np.zeros(NV + 1, np.int32)
        reg = []
        cr_off = np.zeros(NV + 1, np.int32)
        cr_comp = []
        cr = []
        for v in range(NV):
            view = VIEW_ORDER[v]
            for r in machine.dashboard_regions.get(view, ()):
                reg.append(r[:4])
            reg_off[v + 1] = len(reg)
            for comp, r in machine.component_rects.get(view, ()):
                cr_comp.append(self.comp_id[comp])
                cr.append(r[:4])
            cr_off[v + 1] = len(cr)
        self.reg_off = self._ints(reg_off)
        self.reg = self._doubles(reg, 4)
        self.cr_off = self._ints(cr_off)
        self.cr_comp = self._ints(np.array(cr_comp, np.int32))
        self.cr = self._doubles(cr, 4)
        return 0

    cdef dict _transition_tables(self, object machine):
        """Per transition: action, component, list position, end state, the states it
        enters, whether it is dangerous, its params and its feedback text; returns the
        transitions' numbers by identity."""
        cdef int i
        transitions = machine.transitions
        self.n_tr = len(transitions)
        tr_ent_off = np.zeros(self.n_tr + 1, np.int32)
        tr_ent = []
        self.tr_params = []
        self.texts = []
        arrays = {name: np.zeros(self.n_tr, np.int32) for name in ("action", "comp", "index", "end")}
        dangerous = np.zeros(self.n_tr, np.uint8)
        for i, t in enumerate(transitions):
            arrays["action"][i] = ACTION_CODE[t.action] if t.action is not None else (
                A_WAIT if t.component == TIMED_WAIT else -1
            )
            arrays["comp"][i] = self.comp_id.get(t.component, -1)
            arrays["index"][i] = t.index
            arrays["end"][i] = t.end
            dangerous[i] = t.dangerous
            tr_ent.extend(t.entered)
            tr_ent_off[i + 1] = len(tr_ent)
            self.tr_params.append(t.params)
            # The reference's own text for this transition (`apply_transition`; any view
            # will do).
            self.texts.append(
                apply_transition(machine, SimState(t.source, FRONT, False), t)[1].text
            )
        self.tr_action = self._ints(arrays["action"])
        self.tr_comp = self._ints(arrays["comp"])
        self.tr_index = self._ints(arrays["index"])
        self.tr_end = self._ints(arrays["end"])
        self.tr_ent_off = self._ints(tr_ent_off)
        self.tr_ent = self._ints(np.array(tr_ent, np.int32))
        self.tr_dangerous = self._bytes(dangerous)
        return {id(t): i for i, t in enumerate(transitions)}

    cdef int _candidate_tables(self, object machine, dict tr_id) except -1:
        """Per (state, view): the agent transitions with boxes there and their boxes (what
        a click may match); per state, its `timed_wait` transition."""
        cdef int s, v
        sv_off = np.zeros(self.n_states * NV + 1, np.int32)
        cand_tr = []
        cand_roff = [0]
        cand_rect = []
        for s in range(self.n_states):
            for v in range(NV):
                for t, rects in machine.by_state_view.get((s, VIEW_ORDER[v]), ()):
                    cand_tr.append(tr_id[id(t)])
                    cand_rect.extend(rects)
                    cand_roff.append(len(cand_rect))
                sv_off[s * NV + v + 1] = len(cand_tr)
        self.sv_off = self._ints(sv_off)
        self.cand_tr = self._ints(np.array(cand_tr, np.int32))
        self.cand_roff = self._ints(np.array(cand_roff, np.int32))
        self.cand_rect = self._doubles(cand_rect, 5)
        wait_tr = np.array(
            [tr_id[id(w)] if w is not None else -1 for w in machine.wait], np.int32
        )
        self.wait_tr = self._ints(wait_tr)
        return 0

    cdef int* _ints(self, object arr) except NULL:
        arr = np.ascontiguousarray(arr, np.int32)
        if arr.size == 0:
            arr = np.zeros(1, np.int32)
        self._keep.append(arr)
        cdef int[::1] view = arr
        return &view[0]

    cdef unsigned char* _bytes(self, object arr) except NULL:
        arr = np.ascontiguousarray(arr, np.uint8)
        if arr.size == 0:
            arr = np.zeros(1, np.uint8)
        self._keep.append(arr)
        cdef unsigned char[::1] view = arr
        return &view[0]

    cdef double* _doubles(self, list rows, int width) except NULL:
        arr = np.array(rows, np.float64).reshape(-1, width) if rows else np.zeros((1, width))
        arr = np.ascontiguousarray(arr.ravel())
        self._keep.append(arr)
        cdef double[::1] view = arr
        return &view[0]

    cdef KGoal goal(self, int g):
        got = self.goals.get(g)
        if got is None:
            got = KGoal(self, g)
            self.goals[g] = got
        return <KGoal>got

    cdef object c_opt_dyn(self, int state, int view, bint unlocked, int goal):
        key = (state, view, unlocked, goal)
        got = self.dyn_memo.get(key, self)
        if got is self:
            got = c_opt_dynamic(self.machine, state, VIEW_ORDER[view], unlocked, goal)
            self.dyn_memo[key] = got
        return got


cdef class KGoal:
    """Per goal of a machine: distances, and per state (built on first use) the target
    components' rects by view and the views where a target has a bbox (switch classes)."""

    cdef KMachine km
    cdef int goal
    cdef long long* dist
    cdef unsigned char* built
    cdef unsigned char* has_targets
    cdef unsigned int* pos_views
    cdef int* tg_start          # per (state, view): range in tg_comp / tg_rect
    cdef int* tg_end
    cdef IntVec tg_comp
    cdef list tg_rect           # flat x0, y0, x1, y1 per target rect (Python floats)
    cdef double* rects          # tg_rect as C doubles (rebuilt when it grows)
    cdef object _rects_array
    cdef list _keep

    def __init__(self, KMachine km, int goal):
        n = max(km.n_states, 1)
        self.km = km
        self.goal = goal
        dist = np.array(distances(km.machine, goal) or (0,), np.int64)
        built = np.zeros(n, np.uint8)
        has_targets = np.zeros(n, np.uint8)
        pos_views = np.zeros(n, np.uint32)
        tg_start = np.zeros(n * NV, np.int32)
        tg_end = np.zeros(n * NV, np.int32)
        self._keep = [dist, built, has_targets, pos_views, tg_start, tg_end]
        self.dist = _p64(dist)
        self.built = _p8(built)
        self.has_targets = _p8(has_targets)
        self.pos_views = <unsigned int*>_p32(pos_views.view(np.int32))
        self.tg_start = _p32(tg_start)
        self.tg_end = _p32(tg_end)
        self.tg_comp = IntVec(16)
        self.tg_rect = []
        self._rects_array = np.zeros(4)
        self.rects = _pf(self._rects_array)

    cdef int build(self, int s) except -1:
        """Fill state `s`: `target_components` of the reference and, per view, the rects of
        those components (`target_rects`, read from the same table in one pass)."""
        cdef int v
        cdef bint positive
        machine = self.km.machine
        comp_id = self.km.comp_id
        scr = machine.state_component_rects
        targets = target_components(machine, s, self.goal)
        self.has_targets[s] = bool(targets)
        for view in machine.views:
            v = VIEW_CODE[view]
            self.tg_start[s * NV + v] = <int>self.tg_comp.size
            positive = False
            for comp, rects in scr.get((s, view), {}).items():
                if comp in targets:
                    positive = True
                    for r in rects:
                        self.tg_comp.push(comp_id[comp])
                        self.tg_rect.extend(r[:4])
            if positive:
                self.pos_views[s] |= 1u << v
            self.tg_end[s * NV + v] = <int>self.tg_comp.size
        if self.tg_rect:
            self._rects_array = np.array(self.tg_rect, np.float64)
            self.rects = _pf(self._rects_array)
        self.built[s] = 1
        return 0


def kmachine(machine) -> KMachine:
    """The kernel tables of a compiled machine, kept in the machine's own cache."""
    return _kmachine(machine)


cdef KMachine _kmachine(object machine):
    cdef dict cache = machine._cache
    got = cache.get("kernel")
    if got is None:
        got = KMachine(machine)
        cache["kernel"] = got
    return <KMachine>got


# ------------------------------------------------------------------------------ geometry


cdef inline bint _inside(const double* r, double px, double py) noexcept:
    return r[0] <= px <= r[2] and r[1] <= py <= r[3]


cdef inline double _rect_distance(const double* r, double px, double py) noexcept:
    # `_machine.rect_distance`: max() keeps the first of equals; `** 0.5` is C's pow.
    cdef double dx = r[0] - px, dy = r[1] - py, t
    if 0.0 > dx:
        dx = 0.0
    t = px - r[2]
    if t > dx:
        dx = t
    if 0.0 > dy:
        dy = 0.0
    t = py - r[3]
    if t > dy:
        dy = t
    if dx == 0.0:
        return dy
    if dy == 0.0:
        return dx
    return pow(dx * dx + dy * dy, 0.5)


cdef inline bint _in_region(KMachine km, int view, double px, double py) noexcept:
    cdef int i
    for i in range(km.reg_off[view], km.reg_off[view + 1]):
        if _inside(km.reg + 4 * i, px, py):
            return True
    return False


cdef bint _params_match(object required, tuple params):
    """`CompiledTransition.params_match`."""
    cdef Py_ssize_t i, n
    if not required:
        return True
    n = len(<tuple>required)
    if n != len(params):
        return False
    for i in range(n):
        want = (<tuple>required)[i]
        if want != "*" and want != params[i]:
            return False
    return True


# ------------------------------------------------------------------------------ output


ctypedef long long* i64p
ctypedef int* i32p
ctypedef unsigned char* u8p
ctypedef double* f64p


# Output columns: (name, numpy dtype) of the steps ("s_"), episodes ("e_") and goals ("g_").
_STEP_COLUMNS = (
    ("step_k", "i8"), ("step_ep", "i4"), ("scored", "u1"), ("goal_index", "i8"),
    ("goal_state", "i4"), ("view_before", "i4"), ("view_after", "i4"), ("unlocked", "u1"),
    ("unlocked_valid", "u1"), ("action_type", "i4"), ("x", "f8"), ("y", "f8"),
    ("has_coord", "u1"), ("parse_ok", "u1"), ("parse_detail", "i4"), ("kind", "i4"),
    ("text", "i4"), ("state_before", "i4"), ("state_after", "i4"), ("tr_comp", "i4"),
    ("dangerous", "u1"), ("is_switch", "u1"), ("completed", "i8"), ("is_interaction", "u1"),
    ("hit_component", "u1"), ("hit_target", "u1"), ("nearest", "i4"), ("progress", "u1"),
    ("dist_before", "i8"), ("dist_after", "i8"), ("error_type", "i4"), ("error_detail", "i4"),
    ("switch_class", "i4"), ("repetitive", "u1"), ("eer_valid", "u1"),
    ("eer_valid_valid", "u1"), ("distance", "f8"), ("distance_valid", "u1"), ("weight", "i8"),
    ("budget_global_left", "f8"), ("budget_local_left", "f8"), ("diverged", "u1"),
    ("diverged_valid", "u1"), ("timestamp", "f8"), ("timestamp_valid", "u1"),
    ("prompt", "i8"), ("prompt_valid", "u1"), ("completion", "i8"), ("completion_valid", "u1"),
    ("latency", "f8"), ("latency_valid", "u1"),
)
_EPISODE_COLUMNS = (
    ("n_goals", "i8"), ("goals_completed", "i8"), ("success", "u1"), ("termination", "i4"),
    ("l_opt", "i8"), ("l_act", "i8"), ("spl", "f8"), ("state_f1", "f8"), ("n_switches", "i8"),
    ("vsps_switches", "i8"), ("vsps", "f8"), ("vsps_valid", "u1"), ("n_steps", "i8"),
    ("truncated", "i8"), ("diverged", "i8"), ("lam", "f8"), ("budget_global", "f8"),
    ("initial_state", "i4"), ("initial_view", "i4"),
    ("prompt", "i8"), ("prompt_valid", "u1"), ("completion", "i8"), ("completion_valid", "u1"),
    ("latency", "f8"), ("latency_valid", "u1"),
)
_GOAL_COLUMNS = (
    ("episode", "i4"), ("index", "i8"), ("state", "i4"), ("c_opt", "i8"), ("dyn", "i8"),
    ("dyn_valid", "u1"), ("reached", "u1"), ("completed", "u1"), ("started", "i8"),
    ("completed_step", "i8"), ("steps_used", "i8"), ("switches", "i8"), ("perfect", "u1"),
)


cdef class Out:
    """The column buffers of one batch: numpy arrays (`steps`, `episodes`, `goals` dicts),
    raw pointers into them for the loop, and growable lists and texts."""

    cdef readonly dict steps, episodes, goals
    # steps
    cdef i64p step_k, goal_index, completed, dist_before, dist_after, weight
    cdef i32p step_ep, goal_state, view_before, view_after, action_type, parse_detail
    cdef i32p kind, text, state_before, state_after, tr_comp, nearest, error_type
    cdef i32p error_detail, switch_class
    cdef u8p scored, unlocked, unlocked_valid, has_coord, parse_ok, dangerous
    cdef u8p is_switch, is_interaction, hit_component, hit_target, progress
    cdef u8p repetitive, eer_valid, eer_valid_valid, distance_valid, diverged
    cdef u8p diverged_valid, timestamp_valid, prompt_valid, completion_valid, latency_valid
    cdef f64p x, y, distance, budget_global_left, budget_local_left, timestamp, latency
    cdef i64p prompt, completion
    cdef readonly IntVec entered_off, entered, hits_off, hits, div_off, div, params_off
    cdef readonly TextVec output, thinking, action_raw, params, rec_feedback, rec_state, rec_view
    # episodes
    cdef i64p e_n_goals, e_goals_completed, e_l_opt, e_l_act, e_n_switches
    cdef i64p e_vsps_switches, e_n_steps, e_truncated, e_diverged
    cdef u8p e_success, e_vsps_valid, e_prompt_valid, e_completion_valid, e_latency_valid
    cdef i32p e_termination, e_initial_state, e_initial_view
    cdef f64p e_spl, e_state_f1, e_vsps, e_lam, e_budget_global, e_latency
    cdef i64p e_prompt, e_completion
    cdef readonly IntVec e_goals_off, e_goals, e_c_opt, e_visited_off, e_visited
    cdef readonly IntVec e_optimal_off, e_optimal
    # from the inputs, per episode (`Episode.keep_inputs`) and per goal (`instructions`)
    cdef readonly list episode_ids, device_ids, categories, continuations, c_opt_stated
    cdef readonly list instructions
    # goals
    cdef i64p g_index, g_c_opt, g_dyn, g_started, g_completed_step, g_steps_used
    cdef i64p g_switches
    cdef i32p g_episode, g_state
    cdef u8p g_dyn_valid, g_reached, g_completed, g_perfect

    def __init__(self, Py_ssize_t n, Py_ssize_t n_eps, Py_ssize_t n_goals, Py_ssize_t text_bytes):
        self.steps = {name: np.zeros(max(n, 1), dtype) for name, dtype in _STEP_COLUMNS}
        self.episodes = {name: np.zeros(max(n_eps, 1), dtype) for name, dtype in _EPISODE_COLUMNS}
        self.goals = {name: np.zeros(max(n_goals, 1), dtype) for name, dtype in _GOAL_COLUMNS}
        s, e, g = self.steps, self.episodes, self.goals
        self.step_k = _p64(s["step_k"]); self.goal_index = _p64(s["goal_index"])
        self.completed = _p64(s["completed"]); self.dist_before = _p64(s["dist_before"])
        self.dist_after = _p64(s["dist_after"]); self.weight = _p64(s["weight"])
        self.step_ep = _p32(s["step_ep"]); self.goal_state = _p32(s["goal_state"])
        self.view_before = _p32(s["view_before"]); self.view_after = _p32(s["view_after"])
        self.action_type = _p32(s["action_type"]); self.parse_detail = _p32(s["parse_detail"])
        self.kind = _p32(s["kind"]); self.text = _p32(s["text"])
        self.state_before = _p32(s["state_before"]); self.state_after = _p32(s["state_after"])
        self.tr_comp = _p32(s["tr_comp"]); self.nearest = _p32(s["nearest"])
        self.error_type = _p32(s["error_type"]); self.error_detail = _p32(s["error_detail"])
        self.switch_class = _p32(s["switch_class"])
        self.scored = _p8(s["scored"]); self.unlocked = _p8(s["unlocked"])
        self.unlocked_valid = _p8(s["unlocked_valid"]); self.has_coord = _p8(s["has_coord"])
        self.parse_ok = _p8(s["parse_ok"]); self.dangerous = _p8(s["dangerous"])
        self.is_switch = _p8(s["is_switch"]); self.is_interaction = _p8(s["is_interaction"])
        self.hit_component = _p8(s["hit_component"]); self.hit_target = _p8(s["hit_target"])
        self.progress = _p8(s["progress"]); self.repetitive = _p8(s["repetitive"])
        self.eer_valid = _p8(s["eer_valid"]); self.eer_valid_valid = _p8(s["eer_valid_valid"])
        self.distance_valid = _p8(s["distance_valid"]); self.diverged = _p8(s["diverged"])
        self.diverged_valid = _p8(s["diverged_valid"])
        self.timestamp_valid = _p8(s["timestamp_valid"])
        self.x = _pf(s["x"]); self.y = _pf(s["y"]); self.distance = _pf(s["distance"])
        self.budget_global_left = _pf(s["budget_global_left"])
        self.budget_local_left = _pf(s["budget_local_left"]); self.timestamp = _pf(s["timestamp"])
        self.prompt = _p64(s["prompt"]); self.prompt_valid = _p8(s["prompt_valid"])
        self.completion = _p64(s["completion"]); self.completion_valid = _p8(s["completion_valid"])
        self.latency = _pf(s["latency"]); self.latency_valid = _p8(s["latency_valid"])
        self.entered_off = IntVec(n + 1); self.entered = IntVec(n + 1)
        self.hits_off = IntVec(n + 1); self.hits = IntVec(n + 1)
        self.div_off = IntVec(n + 1); self.div = IntVec(16)
        self.params_off = IntVec(n + 1)
        for offsets in (self.entered_off, self.hits_off, self.div_off, self.params_off):
            offsets.push(0)
        self.output = TextVec(text_bytes + 1); self.thinking = TextVec(text_bytes + 1)
        self.action_raw = TextVec(n * 32 + 1); self.params = TextVec(n * 4 + 1)
        self.rec_feedback = TextVec(n * 16 + 1); self.rec_state = TextVec(n * 12 + 1)
        self.rec_view = TextVec(n * 6 + 1)
        self.e_n_goals = _p64(e["n_goals"]); self.e_goals_completed = _p64(e["goals_completed"])
        self.e_l_opt = _p64(e["l_opt"]); self.e_l_act = _p64(e["l_act"])
        self.e_n_switches = _p64(e["n_switches"]); self.e_vsps_switches = _p64(e["vsps_switches"])
        self.e_n_steps = _p64(e["n_steps"]); self.e_truncated = _p64(e["truncated"])
        self.e_diverged = _p64(e["diverged"]); self.e_success = _p8(e["success"])
        self.e_vsps_valid = _p8(e["vsps_valid"]); self.e_termination = _p32(e["termination"])
        self.e_initial_state = _p32(e["initial_state"])
        self.e_initial_view = _p32(e["initial_view"]); self.e_spl = _pf(e["spl"])
        self.e_state_f1 = _pf(e["state_f1"]); self.e_vsps = _pf(e["vsps"]); self.e_lam = _pf(e["lam"])
        self.e_budget_global = _pf(e["budget_global"])
        self.e_prompt = _p64(e["prompt"]); self.e_prompt_valid = _p8(e["prompt_valid"])
        self.e_completion = _p64(e["completion"])
        self.e_completion_valid = _p8(e["completion_valid"])
        self.e_latency = _pf(e["latency"]); self.e_latency_valid = _p8(e["latency_valid"])
        self.e_goals_off = IntVec(n_eps + 1); self.e_goals = IntVec(n_goals + 1)
        self.e_c_opt = IntVec(n_goals + 1)
        self.e_visited_off = IntVec(n_eps + 1); self.e_visited = IntVec(n_eps * 8 + 1)
        self.e_optimal_off = IntVec(n_eps + 1); self.e_optimal = IntVec(n_eps * 8 + 1)
        for offsets in (self.e_goals_off, self.e_visited_off, self.e_optimal_off):
            offsets.push(0)
        self.episode_ids, self.device_ids, self.categories = [], [], []
        self.continuations, self.c_opt_stated, self.instructions = [], [], []
        self.g_index = _p64(g["index"]); self.g_c_opt = _p64(g["c_opt"]); self.g_dyn = _p64(g["dyn"])
        self.g_started = _p64(g["started"]); self.g_completed_step = _p64(g["completed_step"])
        self.g_steps_used = _p64(g["steps_used"]); self.g_switches = _p64(g["switches"])
        self.g_episode = _p32(g["episode"]); self.g_state = _p32(g["state"])
        self.g_dyn_valid = _p8(g["dyn_valid"]); self.g_reached = _p8(g["reached"])
        self.g_completed = _p8(g["completed"]); self.g_perfect = _p8(g["perfect"])


cdef long long* _p64(object arr) except NULL:
    cdef long long[::1] view = arr
    return &view[0]


cdef int* _p32(object arr) except NULL:
    cdef int[::1] view = arr
    return &view[0]


cdef unsigned char* _p8(object arr) except NULL:
    cdef unsigned char[::1] view = arr
    return &view[0]


cdef double* _pf(object arr) except NULL:
    cdef double[::1] view = arr
    return &view[0]


cdef struct Parsed:
    bint ok
    int detail          # -1 when ok
    int kind            # -1 when not ok
    bint has_coord
    double x
    double y


cdef struct Outcome:
    int kind
    int text            # code into the batch's text vocabulary
    int detail          # invalid_action reason, -1 otherwise
    int tr              # transition id, -1 when none
    bint dangerous
    bint switched
    bint unlocked_now


cdef struct Scored:
    # What one scored step did and how it is classified, passed between the stages of
    # `Episode.steps` (the values of `Classifier.classify`, coded).
    int goal_index      # the goal current at the start of the step, and its state
    int goal
    int s0              # state and view before the step
    int v0
    int kind            # the action's code, -1 when it did not parse
    long long completed
    long long d_before
    long long d_after
    bint progress
    bint is_interaction
    int n_hits          # components hit, in `Episode.hit_buf`
    int nearest         # the nearest target component, -1 when none
    double best_d
    bint has_best
    bint hit_target
    long long weight
    int error_type
    int error_detail
    int switch_class
    bint repetitive


cdef inline Outcome _invalid(int detail) noexcept:
    cdef Outcome o
    o.kind = K_INVALID
    o.text = detail
    o.detail = detail
    o.tr = -1
    o.dangerous = False
    o.switched = False
    o.unlocked_now = False
    return o


cdef inline Outcome _plain(int kind, int text) noexcept:
    cdef Outcome o = _invalid(-1)
    o.kind = kind
    o.text = text
    return o


# ------------------------------------------------------------------------------ the step


cdef Outcome _step(
    KMachine km, Parsed* pa, tuple params, int* state, int* view, bint* unlocked, int text_base
) except *:
    """`_step.step` on integer codes; updates (state, view, unlocked) in place."""
    cdef Outcome o
    cdef int v, i, j, tr, best = -1, best_comp = 0, best_index = 0
    cdef double px, py, area, best_area = 0.0
    cdef bint hit = False, found
    cdef const double* r
    if not pa.ok:
        return _invalid(pa.detail if pa.detail >= 0 else D_MALFORMED)
    if pa.kind == A_SWITCH:
        if len(params) != 1:
            return _invalid(D_INVALID_VIEW)
        code = VIEW_CODE.get(params[0])
        if code is None or not (km.offered >> <int>code) & 1:
            return _invalid(D_INVALID_VIEW)
        v = <int>code
        if v == V_DASHBOARD and not unlocked[0]:
            if pa.has_coord and _in_region(km, view[0], pa.x, pa.y):
                view[0] = V_DASHBOARD
                unlocked[0] = True
                o = _plain(K_SWITCHED, T_UNLOCK_SWITCH)
                o.switched = True
                o.unlocked_now = True
                return o
            return _invalid(D_LOCKED)
        view[0] = v
        o = _plain(K_SWITCHED, T_SWITCHED + v)
        o.switched = True
        return o
    if pa.kind == A_WAIT:
        tr = km.wait_tr[state[0]]
        if tr < 0:
            return _plain(K_WAIT_NO_EFFECT, T_WAIT_NO_EFFECT)
        return _apply_tr(km, tr, state, text_base)
    if not (INTERACTABLE >> view[0]) & 1:
        return _invalid(D_AXONOMETRIC)
    if not pa.has_coord:
        return _invalid(D_MISSING_COORD)
    px = pa.x
    py = pa.y
    if not (0.0 <= px <= _SCALE and 0.0 <= py <= _SCALE):
        return _invalid(D_OUT_OF_RANGE)
    if not unlocked[0] and km.has_dashboard and _in_region(km, view[0], px, py):
        unlocked[0] = True
        o = _plain(K_UNLOCKED, T_UNLOCKED)
        o.unlocked_now = True
        return o
    cdef int sv = state[0] * NV + view[0]
    for i in range(km.sv_off[sv], km.sv_off[sv + 1]):
        found = False
        area = 0.0
        for j in range(km.cand_roff[i], km.cand_roff[i + 1]):
            r = km.cand_rect + 5 * j
            if _inside(r, px, py) and (not found or r[4] < area):
                area = r[4]
                found = True
        if not found:
            continue
        hit = True
        tr = km.cand_tr[i]
        if km.tr_action[tr] == pa.kind and _params_match(km.tr_params[tr], params):
            if (
                best < 0
                or area < best_area
                or (area == best_area and (
                    km.tr_comp[tr] < best_comp
                    or (km.tr_comp[tr] == best_comp and km.tr_index[tr] < best_index)
                ))
            ):
                best = tr
                best_area = area
                best_comp = km.tr_comp[tr]
                best_index = km.tr_index[tr]
    if best >= 0:
        return _apply_tr(km, best, state, text_base)
    return _plain(K_OPERATIONAL, T_OPERATIONAL) if hit else _plain(K_NULL, T_NULL)


cdef inline Outcome _apply_tr(KMachine km, int tr, int* state, int text_base) noexcept:
    cdef Outcome o = _plain(K_TRANSITION, text_base + tr)
    o.tr = tr
    o.dangerous = km.tr_dangerous[tr]
    state[0] = km.tr_end[tr]
    return o


# ------------------------------------------------------------------------------ the batch


cdef class Vocab:
    """Per-batch string vocabularies: each machine's states, components (then `timed_wait`,
    which names the wait transitions) and feedback texts get an offset in them."""

    cdef readonly list states, comps
    cdef Names text_utf8      # the feedback texts, their UTF-8 at hand for comparisons
    cdef dict offsets

    def __init__(self):
        self.states = []
        self.comps = []
        self.text_utf8 = Names(FIXED_TEXTS)
        self.offsets = {}

    @property
    def texts(self) -> list:
        """The feedback texts: the fixed ones, then each machine's."""
        return self.text_utf8.strs

    cdef tuple offsets_of(self, KMachine km):
        got = self.offsets.get(id(km))
        if got is None:
            got = (len(self.states), len(self.comps), self.text_utf8.n, km)
            self.states.extend(km.state_names)
            self.comps.extend(km.comp_names)
            self.comps.append(TIMED_WAIT)
            self.text_utf8.extend(km.texts)
            self.offsets[id(km)] = got
        return got


# The feedback kinds and the views, as UTF-8, for comparisons with the recorded values.
cdef Names _KINDS = Names(FEEDBACK_KINDS)
cdef Names _VIEWS = Names(VIEW_ORDER)
cdef Py_ssize_t _LONGEST_VIEW = max([len(v.encode()) for v in VIEW_ORDER])
assert _LONGEST_VIEW <= 32


cdef inline bint _is_kind(const Text* t) noexcept:
    """`t` names a feedback kind (`in FEEDBACK_KINDS`)."""
    cdef Py_ssize_t i
    for i in range(_KINDS.n):
        if _same(t, &_KINDS.at[i]):
            return True
    return False


cdef int _lower_view(const Text* recorded) except -2:
    """The code of the view `recorded.lower()` names, or -1. ASCII text lowers byte by byte
    (A-Z only, as `str.lower` does); other text is lowered by `str.lower`, which may make
    ASCII of it (the Kelvin sign U+212A lowers to 'k')."""
    cdef char[32] low
    cdef Py_ssize_t i, v
    cdef char c
    cdef Text t
    if not recorded.ascii:
        code = VIEW_CODE.get(_decoded(recorded).lower())
        return -1 if code is None else <int>code
    if recorded.size > _LONGEST_VIEW:
        return -1
    for i in range(recorded.size):
        c = recorded.data[i]
        low[i] = c + 32 if 65 <= c <= 90 else c  # A-Z
    t.data = low
    t.size = recorded.size
    for v in range(NV):
        if _same(&t, &_VIEWS.at[v]):
            return <int>v
    return -1


cdef inline Py_ssize_t _n_steps(object log) except -1:
    """The number of steps of a log: a `LogLine` or msgspec's `EpisodeLog`."""
    if type(log) is LogLine:
        return (<LogLine>log).n_steps
    return len(log.steps)


cdef object _NO_STEP = LogStep()  # a step with neither output nor action: "no action"


cdef object _reference_parse(const StepIn* si):
    """The reference parser's result for a step the compiled grammar leaves to it: of the
    `LogStep` itself (a structured action, or its output) when there is one, else (a decoded
    line, whose steps have no structured action) of its output, or "no action" without."""
    if si.step != NULL:
        return parse_log_step(<object>si.step)
    if si.output.data != NULL:
        return parse_action(_decoded(&si.output))
    return parse_log_step(_NO_STEP)


def replay_batch(list episodes, Vocab vocab, dict param_cache):
    """Replay `episodes` (items with `machine`, `task`, `setup`, `log`, `lam`) into an `Out`.

    `param_cache` maps raw parameter words to their normalised form (kept across batches,
    bounded by the caller)."""
    cdef Py_ssize_t n = 0, n_goals = 0, text_bytes = 0, e, row = 0, goal_row = 0
    for ep in episodes:
        n += _n_steps(ep.log)
        n_goals += len(ep.setup.goals)
    cdef Out out = Out(n, len(episodes), n_goals, n * 256)
    cdef Episode run = Episode(out, vocab, param_cache)
    for e in range(len(episodes)):
        run.start(episodes[e], e)
        row = run.steps(row)
        run.finish(goal_row)
        run.keep_inputs()
        goal_row += run.n_goals
    return out


@cython.final
cdef class Episode:
    """One episode being replayed: the simulator state, goals, budgets and the classifier's
    history (as `replay_episode` and `Classifier` keep them)."""

    cdef Out out
    cdef KMachine km
    cdef object ep, setup
    cdef Vocab vocab
    cdef dict param_cache
    cdef Py_ssize_t e
    cdef int sb, cb, tb, n_goals, current, state, view, termination
    cdef bint unlocked
    cdef double lam, budget_global, budget_local, latency
    cdef long long l_opt, taken, n_switches, diverged_steps, truncated_steps, prompt, completion
    cdef bint has_prompt, has_completion, has_latency
    cdef IntVec goal_ids, started, completed_at, steps_used, switches, failures, visited
    cdef IntVec c_opt, seen_state, hit_buf, in_optimal
    cdef list dyn
    cdef Repeats repeats      # the batch's, emptied for this episode
    cdef dict param_ids       # params -> number, for the batch
    cdef tuple _params
    cdef Py_ssize_t _row
    cdef Py_ssize_t n_steps   # the log's
    cdef KGoal _kg            # the current goal's tables, kept while the goal stays
    cdef int _kg_goal

    def __init__(self, Out out, Vocab vocab, dict param_cache):
        # One Episode replays every episode of a batch in turn (`start`): its buffers are
        # made once and refilled, where an object per episode made and freed 13 of them.
        self.out = out
        self.vocab = vocab
        self.param_cache = param_cache
        self.repeats = Repeats()
        self.param_ids = {}
        self.goal_ids, self.c_opt, self.started, self.completed_at = _vecs(4)
        self.steps_used, self.switches, self.failures, self.seen_state = _vecs(4)
        self.hit_buf, self.visited, self.in_optimal = _vecs(3)

    cdef int start(self, object ep, Py_ssize_t e) except -1:
        """Begin episode `e` of the batch (`ep`): as `replay_episode` sets up its session."""
        cdef int g
        cdef KMachine km = _kmachine(ep.machine)
        self.ep = ep
        self.setup = setup = ep.setup
        self.km = km
        self.e = e
        cdef tuple at = self.vocab.offsets_of(km)
        self.sb, self.cb, self.tb = at[0], at[1], at[2]
        goals = setup.goals
        c_opt = setup.plan.c_opt
        self.n_goals = len(goals)
        _refill(self.goal_ids, self.n_goals, 0)
        _refill(self.c_opt, self.n_goals, 0)
        self.l_opt = 0
        for g in range(self.n_goals):
            self.goal_ids.data[g] = goals[g]
            self.c_opt.data[g] = c_opt[g]
            self.l_opt += c_opt[g]
        self.lam = float(ep.lam)
        self.budget_global = self.lam * self.l_opt
        self.budget_local = self.lam * <long long>self.c_opt.data[0]
        self.state = setup.start_state
        self.view = VIEW_CODE[setup.initial_view]
        self.unlocked = False
        self.current = 0
        self.termination = -1
        self.taken = self.n_switches = self.diverged_steps = self.truncated_steps = 0
        self.prompt = self.completion = 0
        self.latency = 0.0
        self.has_prompt = self.has_completion = self.has_latency = False
        _refill(self.started, self.n_goals, -1)
        _refill(self.completed_at, self.n_goals, -1)
        _refill(self.steps_used, self.n_goals, 0)
        _refill(self.switches, self.n_goals, 0)
        _refill(self.failures, self.n_goals * km.n_comps + 1, 0)
        _refill(self.seen_state, km.n_states + 1, 0)
        _refill(self.hit_buf, km.n_comps + 1, 0)
        self.visited.size = 0
        for s in setup.reset_states:
            self._visit(s)
        self.started.data[0] = 0
        self.dyn = [None] * self.n_goals
        self.dyn[0] = km.c_opt_dyn(self.state, self.view, False, self.goal_ids.data[0])
        self.repeats.clear()
        self._kg = None
        self._kg_goal = -1
        return 0

    cdef inline int _visit(self, int s) except -1:
        if not self.seen_state.data[s]:
            self.seen_state.data[s] = 1
            self.visited.push(s)
        return 0

    cdef int _parse(self, const StepIn* si, Parsed* pa) except -1:
        """Parse a step (PROTOCOL §2) and write the columns a truncated step has too;
        `self._params` holds its params."""
        cdef Out out = self.out
        cdef FastParse fp
        cdef const char* s = si.output.data
        cdef Py_ssize_t size = si.output.size
        pa.x = pa.y = 0.0
        self._params = ()
        fp.status = PARSE_FALLBACK
        if s != NULL:
            parse_utf8(s, size, si.output.ascii, &fp)
        if fp.status != PARSE_FALLBACK:
            out.output.push_bytes(s, size)
            if fp.thinking.end > fp.thinking.start:
                out.thinking.push_bytes(s + fp.thinking.start, fp.thinking.end - fp.thinking.start)
            else:
                out.thinking.push_null()
            pa.has_coord = False
            pa.kind = -1
            pa.ok = fp.status == PARSE_OK
            if fp.status == PARSE_NO_ACTION:
                out.action_raw.push_bytes(s, 0)
            else:
                out.action_raw.push_bytes(
                    s + fp.action_text.start, fp.action_text.end - fp.action_text.start
                )
            pa.detail = -1 if pa.ok else _STATUS_DETAIL[fp.status]
            if pa.ok:
                pa.kind = fp.kind
                pa.has_coord = fp.has_coord
                pa.x = fp.x
                pa.y = fp.y
                if fp.n_params:
                    self._params = self._param_words(s, &fp)
        else:
            parsed = _reference_parse(si)
            out.output.push_text(&si.output)
            if parsed.thinking:
                out.thinking.push_str(parsed.thinking)
            else:
                out.thinking.push_null()
            out.action_raw.push_str(parsed.action_text)
            action = parsed.action
            pa.ok = parsed.ok
            pa.detail = -1 if parsed.detail is None else DETAIL_CODE[parsed.detail]
            pa.kind = -1
            pa.has_coord = False
            if action is not None:
                pa.kind = ACTION_CODE[action.type]
                coord = action.coord
                if coord is not None:
                    pa.has_coord = True
                    pa.x = coord[0]
                    pa.y = coord[1]
                self._params = action.params
        cdef Py_ssize_t row = self._row
        out.action_type[row] = pa.kind if pa.ok else -1
        out.has_coord[row] = pa.ok and pa.has_coord
        if out.has_coord[row]:
            out.x[row] = pa.x
            out.y[row] = pa.y
        out.parse_ok[row] = pa.ok
        out.parse_detail[row] = pa.detail
        for param in self._params:
            out.params.push_str(param)
        out.params_off.push(<int>out.params.valid.size)
        return 0

    cdef tuple _param_words(self, const char* s, FastParse* fp):
        """The parsed params, each word normalised once per process (`param_cache`): decoded
        straight from the response's bytes into a tuple, with no bytes or list between."""
        cdef int i
        cdef dict cache = self.param_cache
        cdef tuple words = PyTuple_New(fp.n_params)
        for i in range(fp.n_params):
            word = PyUnicode_DecodeUTF8(
                s + fp.params[i].start, fp.params[i].end - fp.params[i].start, NULL
            )
            norm = cache.get(word)
            if norm is None:
                norm = normalize_param(word)
                cache[word] = norm
            Py_INCREF(norm)  # PyTuple_SET_ITEM takes a reference
            PyTuple_SET_ITEM(words, i, norm)
        return words

    cdef int _usage(self, const StepIn* si, Py_ssize_t row) except -1:
        """The step's recorded tokens and latency, added to the episode's sums as
        `EpisodeSession._usage` adds them (the first value recorded starts a sum)."""
        cdef Out out = self.out
        if si.has_prompt:
            _count(si.prompt, out.prompt, out.prompt_valid, row, &self.prompt, &self.has_prompt)
        if si.has_completion:
            _count(si.completion, out.completion, out.completion_valid, row, &self.completion,
                   &self.has_completion)
        if si.has_latency:
            out.latency[row] = si.latency
            out.latency_valid[row] = 1
            self.latency = si.latency if not self.has_latency else self.latency + si.latency
            self.has_latency = True
        return 0

    # The loop over an episode's steps, one method per stage. Episode is final, so each
    # call is a direct C call (inlined where the C compiler sees fit): splitting the loop
    # costs nothing measurable (docs/PERFORMANCE.md, issue 24).

    cdef Py_ssize_t steps(self, Py_ssize_t row) except -1:
        """Every logged step into its row, from `row` on; returns the next row. A step is
        parsed and what the log recorded kept whatever happens; once the episode has
        terminated a step is truncated (nothing scored), else simulated, scored, written,
        checked for termination and compared with what the log recorded.

        Each step is read through a `StepIn`: a decoded line's own (`LogLine`), or one
        filled from each of msgspec's `LogStep`s (held by the log's list meanwhile)."""
        cdef Out out = self.out
        cdef LogLine line = None
        cdef list steps = None, hold = []
        cdef Py_ssize_t k
        cdef StepIn filled
        cdef const StepIn* si = &filled
        cdef Parsed pa
        cdef Outcome oc
        cdef Scored sc
        log = self.ep.log
        if type(log) is LogLine:
            line = <LogLine>log
            self.n_steps = line.n_steps
        else:
            steps = log.steps
            self.n_steps = len(steps)
        for k in range(self.n_steps):
            if line is not None:
                si = &line.steps[k]
            else:
                if hold:
                    del hold[:]
                _step_in(steps[k], &filled, hold)
            self._row = row
            out.step_k[row] = k
            out.step_ep[row] = self.e
            self._parse(si, &pa)
            out.rec_feedback.push_text(&si.feedback)
            out.rec_state.push_text(&si.state)
            out.rec_view.push_text(&si.view)
            self._timestamp(si, row)
            self._usage(si, row)
            if self.termination >= 0:  # after termination: truncated, nothing scored
                self.truncated_steps += 1
                out.entered_off.push(<int>out.entered.size)
                out.hits_off.push(<int>out.hits.size)
                out.div_off.push(<int>out.div.size)
            else:
                self._simulate(k, &pa, &oc, &sc)
                self._score(&pa, &oc, &sc)
                self._write(row, &pa, &oc, &sc)
                self._terminate()
                self._diverge(si, &oc, row)
            row += 1
        return row

    cdef inline int _timestamp(self, const StepIn* si, Py_ssize_t row) except -1:
        """The recorded time of the step, in seconds (`timestamp_seconds`), when it has one."""
        if si.ts_kind == TS_NUMBER:
            self.out.timestamp[row] = si.ts
            self.out.timestamp_valid[row] = 1
        elif si.ts_kind == TS_TEXT:
            ts = timestamp_seconds(_decoded(&si.ts_text))
            if ts is not None:
                self.out.timestamp[row] = ts
                self.out.timestamp_valid[row] = 1
        return 0

    cdef inline int _simulate(self, Py_ssize_t k, Parsed* pa, Outcome* oc, Scored* sc) except -1:
        """The step on the device (PROTOCOL §3), then goals and budgets as
        `EpisodeSession.advance` keeps them: each goal entered in turn completes at k
        (`advance_goals`), the local budget is refreshed for the goals that became current
        (`refreshed_budget`), and C_opt_dyn is taken for the new current goal."""
        cdef KMachine km = self.km
        cdef int* goal_ids = self.goal_ids.data
        cdef int first, c, g, i
        sc.s0 = self.state
        sc.v0 = self.view
        sc.goal_index = self.current
        sc.goal = goal_ids[sc.goal_index]
        oc[0] = _step(km, pa, self._params, &self.state, &self.view, &self.unlocked, self.tb)
        if oc.tr >= 0:
            first = self.current
            for i in range(km.tr_ent_off[oc.tr], km.tr_ent_off[oc.tr + 1]):
                c = km.tr_ent[i]
                self.out.entered.push(self.sb + c)
                self._visit(c)
                if self.current < self.n_goals and c == goal_ids[self.current]:
                    self.completed_at.data[self.current] = k
                    if self.current != first:
                        self.started.data[self.current] = k
                        self.dyn[self.current] = 0
                    self.current += 1
            if first < self.current < self.n_goals:
                self.started.data[self.current] = k + 1
        self.out.entered_off.push(<int>self.out.entered.size)
        sc.completed = self.current - sc.goal_index
        self.taken += 1
        self.steps_used.data[sc.goal_index] += 1
        if oc.switched:
            self.n_switches += 1
            self.switches.data[sc.goal_index] += 1
        self.budget_local -= 1
        if sc.completed:
            for g in range(sc.goal_index + 1, min(self.current + 1, self.n_goals)):
                if self.lam * <long long>self.c_opt.data[g] > self.budget_local:
                    self.budget_local = self.lam * <long long>self.c_opt.data[g]
            if self.current < self.n_goals:
                self.dyn[self.current] = km.c_opt_dyn(
                    self.state, self.view, self.unlocked, goal_ids[self.current]
                )
        return 0

    cdef inline int _score(self, Parsed* pa, Outcome* oc, Scored* sc) except -1:
        """The step's classification (PROTOCOL §5), as `Classifier.classify`: progress,
        the components hit, the nearest target, the error, repetition."""
        if sc.goal != self._kg_goal:
            self._kg = self.km.goal(sc.goal)
            self._kg_goal = sc.goal
        cdef KGoal kg = self._kg
        if not kg.built[sc.s0]:
            kg.build(sc.s0)
        sc.kind = pa.kind if pa.ok else -1
        sc.d_before = kg.dist[sc.s0]
        sc.d_after = kg.dist[self.state]
        sc.progress = sc.completed > 0 or sc.d_after < sc.d_before
        sc.is_interaction = (
            0 <= sc.kind < A_SWITCH and pa.has_coord and (INTERACTABLE >> sc.v0) & 1
            and oc.kind != K_UNLOCKED
        )
        self._hits(pa, sc)
        self._nearest_target(kg, pa, sc)
        self._error(kg, pa, oc, sc)
        self._repetition(pa, sc)
        return 0

    cdef inline int _hits(self, Parsed* pa, Scored* sc) except -1:
        """The components whose boxes in the view hold the point, into `hit_buf`: each once,
        in ascending order (the order of their names), as the columns and the repetition
        key take them."""
        cdef KMachine km = self.km
        cdef int i, j, comp
        cdef int* buf = self.hit_buf.data
        sc.n_hits = 0
        if sc.kind >= 0 and pa.has_coord and sc.kind != A_SWITCH:
            for i in range(km.cr_off[sc.v0], km.cr_off[sc.v0 + 1]):
                if _inside(km.cr + 4 * i, pa.x, pa.y):
                    comp = km.cr_comp[i]
                    j = sc.n_hits  # insertion into the sorted few hit so far
                    while j > 0 and buf[j - 1] > comp:
                        j -= 1
                    if j > 0 and buf[j - 1] == comp:
                        continue
                    memmove(buf + j + 1, buf + j, (sc.n_hits - j) * sizeof(int))
                    buf[j] = comp
                    sc.n_hits += 1
        return 0

    cdef inline int _nearest_target(self, KGoal kg, Parsed* pa, Scored* sc) except -1:
        """For an interaction: the nearest target box (ties to the component first by name),
        whether one holds the point, and the weight of the attempt on that target."""
        cdef int i, comp, at
        cdef double d
        sc.nearest = -1
        sc.best_d = 0.0
        sc.has_best = False
        sc.hit_target = False
        sc.weight = 0
        if not sc.is_interaction:
            return 0
        at = sc.s0 * NV + sc.v0
        for i in range(kg.tg_start[at], kg.tg_end[at]):
            d = _rect_distance(kg.rects + 4 * i, pa.x, pa.y)
            comp = kg.tg_comp.data[i]
            if d == 0.0:
                sc.hit_target = True
            if not sc.has_best or d < sc.best_d or (d == sc.best_d and comp < sc.nearest):
                sc.best_d = d
                sc.nearest = comp
                sc.has_best = True
        if sc.has_best:
            i = sc.goal_index * self.km.n_comps + sc.nearest
            sc.weight = 1 + self.failures.data[i]
            if not sc.progress:
                self.failures.data[i] = <int>sc.weight
        return 0

    cdef inline int _error(self, KGoal kg, Parsed* pa, Outcome* oc, Scored* sc) except -1:
        """The error type and detail of the step, and the class of a switch (PROTOCOL §5.2)."""
        cdef int s0 = sc.s0
        sc.error_type = -1
        sc.error_detail = -1
        sc.switch_class = -1
        if not pa.ok:
            sc.error_type = E_ACTION
            sc.error_detail = pa.detail
        elif sc.kind == A_SWITCH:
            if not oc.switched:
                sc.error_type = E_ACTION
                sc.error_detail = oc.detail
            elif kg.has_targets[s0]:
                sc.switch_class = _switch_code(
                    (kg.pos_views[s0] >> sc.v0) & 1, (kg.pos_views[s0] >> self.view) & 1
                )
                if sc.switch_class == SC_NN:
                    sc.error_type = E_SWITCH_NN
                elif sc.switch_class == SC_PN:
                    sc.error_type = E_SWITCH_PN
        elif sc.kind == A_WAIT:
            if oc.kind == K_WAIT_NO_EFFECT:
                sc.error_type = E_WAITING
                sc.error_detail = D_NO_EFFECT
        elif oc.kind == K_INVALID:
            if oc.detail == D_OUT_OF_RANGE:
                sc.error_type = E_INVALID_COORD
                sc.error_detail = D_OUT_OF_RANGE
            else:
                sc.error_type = E_ACTION
                sc.error_detail = oc.detail
        elif oc.kind != K_UNLOCKED and not sc.progress:
            if sc.n_hits == 0:
                sc.error_type = E_INVALID_COORD
            elif not sc.hit_target:
                sc.error_type = E_COMPONENT
            else:
                sc.error_type, sc.error_detail = _target_error(
                    self.km, kg, s0, sc.goal, sc.v0, sc.kind, pa.x, pa.y, self._params
                )
        return 0

    cdef inline int _repetition(self, Parsed* pa, Scored* sc) except -1:
        """Whether the step repeats an earlier one of the same goal (same state, action,
        place, params and view), remembering it otherwise."""
        cdef RepKey key
        sc.repetitive = False
        if pa.ok and sc.kind != A_SWITCH:
            key.goal_index = sc.goal_index
            key.s0 = sc.s0
            key.kind = sc.kind
            key.v0 = sc.v0
            key.params = self._params_id()
            key.gx = key.gy = 0.0
            key.n_hits = 0
            if not pa.has_coord:
                key.where = 0
            elif sc.n_hits:
                key.where = 1
                key.n_hits = sc.n_hits
            else:
                key.where = 2
                key.gx = floor(pa.x / 10 + 0.5)
                key.gy = floor(pa.y / 10 + 0.5)
                if not (isfinite(key.gx) and isfinite(key.gy)):  # math.floor's error, as
                    math.floor(pa.x / 10 + 0.5), math.floor(pa.y / 10 + 0.5)  # the reference's
            sc.repetitive = self.repeats.seen(&key, self.hit_buf.data)
        return 0

    cdef inline int _params_id(self) except -1:
        """The step's params by number: 0 for none, else their number in the batch."""
        if not self._params:
            return 0
        got = self.param_ids.get(self._params)
        if got is None:
            got = len(self.param_ids) + 1
            self.param_ids[self._params] = got
        return got

    cdef inline int _write(self, Py_ssize_t row, Parsed* pa, Outcome* oc, Scored* sc) except -1:
        """The scored step's columns."""
        cdef Out out = self.out
        cdef KMachine km = self.km
        cdef int sb = self.sb, cb = self.cb, comp
        out.scored[row] = 1
        out.goal_index[row] = sc.goal_index
        out.goal_state[row] = sb + sc.goal
        out.view_before[row] = sc.v0
        out.view_after[row] = self.view
        out.unlocked[row] = self.unlocked
        out.unlocked_valid[row] = km.has_dashboard
        out.kind[row] = oc.kind
        out.text[row] = oc.text
        out.state_before[row] = sb + sc.s0
        out.state_after[row] = sb + self.state
        if oc.tr < 0:
            out.tr_comp[row] = -1
        elif km.tr_comp[oc.tr] >= 0:
            out.tr_comp[row] = cb + km.tr_comp[oc.tr]
        else:  # a timed_wait transition
            out.tr_comp[row] = cb + km.n_comps
        out.dangerous[row] = oc.dangerous
        out.is_switch[row] = oc.switched
        out.completed[row] = sc.completed
        out.is_interaction[row] = sc.is_interaction
        out.hit_component[row] = sc.n_hits > 0
        out.hit_target[row] = sc.hit_target
        for comp in range(sc.n_hits):
            out.hits.push(cb + self.hit_buf.data[comp])
        out.hits_off.push(<int>out.hits.size)
        out.nearest[row] = -1 if sc.nearest < 0 else cb + sc.nearest
        out.progress[row] = sc.progress
        out.dist_before[row] = sc.d_before
        out.dist_after[row] = sc.d_after
        out.error_type[row] = sc.error_type
        out.error_detail[row] = sc.error_detail
        out.switch_class[row] = sc.switch_class
        out.repetitive[row] = sc.repetitive
        if sc.kind != A_SWITCH:
            out.eer_valid_valid[row] = 1
            if pa.ok:
                out.eer_valid[row] = (
                    (oc.kind == K_TRANSITION or oc.unlocked_now) and not oc.dangerous
                    and not sc.repetitive
                )
        if sc.has_best:
            out.distance[row] = sc.best_d
            out.distance_valid[row] = 1
            out.weight[row] = sc.weight
        out.budget_global_left[row] = self.budget_global - self.taken
        out.budget_local_left[row] = self.budget_local
        return 0

    cdef inline int _terminate(self) noexcept:
        """Termination after a scored step: success, then the global budget, then the local
        one (`termination_after`)."""
        if self.current >= self.n_goals:
            self.termination = 0
        elif self.taken >= self.budget_global:
            self.termination = 1
        elif self.budget_local <= 0:
            self.termination = 2
        return 0

    cdef inline int _diverge(self, const StepIn* si, Outcome* oc, Py_ssize_t row) except -1:
        """The recorded values against the replay (PROTOCOL §7.2): a recorded feedback kind
        is compared with the kind, a text with the text. Compared as UTF-8 (equal bytes,
        equal str), with the replay's names' UTF-8 kept once (`Names`)."""
        cdef Out out = self.out
        cdef int div_mask = 0, c
        cdef const Text* feedback = &si.feedback
        cdef const Text* state = &si.state
        cdef const Text* view = &si.view
        # Equal to what the replay gives is checked first; the other readings after.
        if feedback.data != NULL or state.data != NULL or view.data != NULL:
            if feedback.data != NULL and not _same(feedback, &_KINDS.at[oc.kind]):
                if not _same(feedback, &self.vocab.text_utf8.at[oc.text]) or _is_kind(feedback):
                    div_mask |= 1  # another kind, or a text that is not the replay's
            if state.data != NULL and not _same(state, &self.km.state_utf8.at[self.state]):
                div_mask |= 2
            if view.data != NULL and not _same(view, &_VIEWS.at[self.view]):
                if _lower_view(view) != self.view:
                    div_mask |= 4
            out.diverged_valid[row] = 1
            if div_mask:
                out.diverged[row] = 1
                self.diverged_steps += 1
                for c in range(3):
                    if (div_mask >> c) & 1:
                        out.div.push(c)
        out.div_off.push(<int>out.div.size)
        return 0

    cdef int keep_inputs(self) except -1:
        """What the tables take from the episode's inputs as they are (its keys, its
        continuation, the task's stated C_opt and its goals' instructions: the task's list cut
        to the goals, None past its end), gathered here while they are at hand: passes in
        Python over the batch's inputs cost about 0.1 us a step."""
        cdef Out out = self.out
        task = self.ep.task
        machine = self.ep.machine
        out.episode_ids.append(task.episode_id)
        out.device_ids.append(machine.device_id)
        out.categories.append(machine.category)
        out.continuations.append(self.ep.log.continuation)
        out.c_opt_stated.append(task.c_opt)
        given = task.instructions
        out.instructions.extend(given[:self.n_goals])
        if self.n_goals > len(given):
            out.instructions.extend([None] * (self.n_goals - len(given)))
        return 0

    cdef int finish(self, Py_ssize_t goal_row) except -1:
        """The episode row and the goal rows (the end of `replay_episode`)."""
        cdef Out out = self.out
        cdef KMachine km = self.km
        cdef Py_ssize_t e = self.e, r
        cdef int g, i, inter = 0, sb = self.sb, n_goals = self.n_goals
        cdef bint success = self.current == n_goals
        cdef long long vsps_switches = 0, l_act = self.taken, longest
        cdef IntVec in_optimal = self.in_optimal
        _refill(in_optimal, km.n_states + 1, 0)
        optimal = _optimal_states(self.setup)
        for s in optimal:
            in_optimal.data[<int>s] = 1
            out.e_optimal.push(sb + <int>s)
        out.e_optimal_off.push(<int>out.e_optimal.size)
        for i in range(self.visited.size):
            out.e_visited.push(sb + self.visited.data[i])
            inter += in_optimal.data[self.visited.data[i]]
        out.e_visited_off.push(<int>out.e_visited.size)
        for g in range(n_goals):
            if self.completed_at.data[g] >= 0:
                vsps_switches += self.switches.data[g]
            out.e_goals.push(sb + self.goal_ids.data[g])
            out.e_c_opt.push(self.c_opt.data[g])
        out.e_goals_off.push(<int>out.e_goals.size)
        longest = l_act if l_act > self.l_opt else self.l_opt
        out.e_n_goals[e] = n_goals
        out.e_goals_completed[e] = self.current
        out.e_success[e] = success
        if self.termination >= 0:
            out.e_termination[e] = self.termination
        else:  # the log ran out first: log_ended, or how the harness ended it (`ended`)
            ended = self.ep.log.ended  # an attribute of either kind of log
            out.e_termination[e] = TERMINATIONS.index(ended) if ended is not None else 3
        out.e_l_opt[e] = self.l_opt
        out.e_l_act[e] = l_act
        if success:
            out.e_spl[e] = (<double>self.l_opt / <double>longest) if self.l_opt else 1.0
        out.e_state_f1[e] = 2.0 * inter / <double>(self.visited.size + len(optimal))
        out.e_n_switches[e] = self.n_switches
        out.e_vsps_switches[e] = vsps_switches
        if self.current:
            out.e_vsps[e] = <double>vsps_switches / <double>self.current
            out.e_vsps_valid[e] = 1
        out.e_n_steps[e] = self.n_steps
        out.e_truncated[e] = self.truncated_steps
        out.e_diverged[e] = self.diverged_steps
        out.e_lam[e] = self.lam
        out.e_budget_global[e] = self.budget_global
        out.e_initial_state[e] = sb + <int>self.setup.initial_state
        out.e_initial_view[e] = VIEW_CODE[self.setup.initial_view]
        out.e_prompt[e] = self.prompt
        out.e_prompt_valid[e] = self.has_prompt
        out.e_completion[e] = self.completion
        out.e_completion_valid[e] = self.has_completion
        out.e_latency[e] = self.latency
        out.e_latency_valid[e] = self.has_latency
        for g in range(n_goals):
            r = goal_row + g
            dyn = self.dyn[g]
            out.g_episode[r] = <int>e
            out.g_index[r] = g
            out.g_state[r] = sb + self.goal_ids.data[g]
            out.g_c_opt[r] = self.c_opt.data[g]
            if dyn is not None:
                out.g_dyn[r] = dyn
                out.g_dyn_valid[r] = 1
            out.g_reached[r] = self.started.data[g] >= 0
            out.g_completed[r] = self.completed_at.data[g] >= 0
            out.g_started[r] = self.started.data[g]
            out.g_completed_step[r] = self.completed_at.data[g]
            out.g_steps_used[r] = self.steps_used.data[g]
            out.g_switches[r] = self.switches.data[g]
            out.g_perfect[r] = (
                self.completed_at.data[g] >= 0 and dyn is not None
                and self.steps_used.data[g] <= dyn
            )
        return 0


cdef inline int _count(long long n, i64p column, u8p valid, Py_ssize_t row, long long* total,
                       bint* has) noexcept:
    """A recorded token count into its column and the episode's sum."""
    column[row] = n
    valid[row] = 1
    total[0] = n if not has[0] else total[0] + n
    has[0] = True
    return 0


cdef tuple _vecs(int n):
    return tuple([IntVec(16) for _ in range(n)])


cdef int _refill(IntVec vec, Py_ssize_t n, int value) except -1:
    """`vec` as n times `value` (room for one at least, as IntVec(0) has)."""
    cdef Py_ssize_t i
    if vec.cap < n:
        vec._grow(n)
    for i in range(n):
        vec.data[i] = value
    vec.size = n
    return 0


cdef inline int _switch_code(unsigned int start_positive, unsigned int end_positive) noexcept:
    if start_positive:
        return SC_PP if end_positive else SC_PN
    return SC_NP if end_positive else SC_NN


cdef tuple _target_error(KMachine km, KGoal kg, int s, int goal, int view, int kind, double px,
                         double py, tuple params):
    """A target hit without progress (`Classifier._interaction_error` with a hit target): the
    candidates are the progressing transitions from `s` with an atomic action and a box of
    their own in `view` holding the point; none of the action's type is a wrong action, a
    matching type with no matching params a params error, else a component selection."""
    cdef int i, j, tr, e
    cdef bint same_type = False
    cdef bint progressing
    cdef long long ds = kg.dist[s]
    for i in range(km.sv_off[s * NV + view], km.sv_off[s * NV + view + 1]):
        tr = km.cand_tr[i]
        if not (0 <= km.tr_action[tr] < A_SWITCH):
            continue
        progressing = kg.dist[km.tr_end[tr]] < ds
        if not progressing:
            for e in range(km.tr_ent_off[tr], km.tr_ent_off[tr + 1]):
                if km.tr_ent[e] == goal:
                    progressing = True
                    break
        if not progressing:
            continue
        for j in range(km.cand_roff[i], km.cand_roff[i + 1]):
            if _inside(km.cand_rect + 5 * j, px, py):
                break
        else:
            continue
        if km.tr_action[tr] == kind:
            same_type = True
            if _params_match(km.tr_params[tr], params):
                return E_COMPONENT, -1
    if not same_type:
        return E_ACTION, D_WRONG_ACTION
    return E_PARAMS, -1


cdef tuple _optimal_states(object setup):
    """The optimal path's states in first-visit order (reset states, then the plan's)."""
    seen = {}
    for s in setup.reset_states:
        seen.setdefault(s, None)
    for s in setup.plan.states:
        seen.setdefault(s, None)
    return tuple(seen)
