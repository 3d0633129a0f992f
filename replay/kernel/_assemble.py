"""Arrow tables from the kernel's column buffers: one `take` per coded string column, numpy
arrays with validity for the rest, text buffers wrapped as they are."""

from __future__ import annotations

import numpy as np
import pyarrow as pa

from ..semantics import (
    ACTION_NAMES,
    ERROR_DETAILS,
    ERROR_GROUPS,
    ERROR_TYPES,
    FEEDBACK_KINDS,
    INF,
    ORIGINS,
    SWITCH_CLASSES,
    TERMINATIONS,
    VIEW_ORDER,
    Continuation,
    EpisodeRow,
    GoalRow,
    Prices,
    StepRow,
    arrow_schema,
    py_column,
    validity_bitmap,
)
from ._words import Words

_VIEWS = Words(VIEW_ORDER)
_ACTIONS = Words(ACTION_NAMES)
_DETAILS = Words(ERROR_DETAILS)
_KINDS = Words(FEEDBACK_KINDS)
_ERROR_TYPES = Words(ERROR_TYPES)
_ERROR_GROUPS = Words([ERROR_GROUPS[t] for t in ERROR_TYPES])
_SWITCH_CLASSES = Words(SWITCH_CLASSES)
_TERMINATIONS = Words(TERMINATIONS)
_DIVERGENCE_FIELDS = Words(("feedback", "state", "view"))
_ORIGINS = Words(ORIGINS)
_PREFIX, _FIX, _AGENT = (ORIGINS.index(o) for o in ("prefix", "fix", "agent"))


_NUMPY_TYPES = {pa.int32(): np.int32, pa.int64(): np.int64, pa.float64(): np.float64}


def numbers(values: np.ndarray, type_: pa.DataType, valid: np.ndarray | None = None) -> pa.Array:
    """A numeric or boolean column; null where `valid` is false. Made from its buffers, as
    every column here: `pa.array` imports pandas on its first call (a quarter of a second
    of CPU in each process that replays), and checks for pandas' types on every call."""
    if type_ == pa.bool_():
        data = np.packbits(values.astype(np.bool_), bitorder="little")
    else:
        data = np.ascontiguousarray(values, _NUMPY_TYPES[type_])
    bitmap, nulls = (None, 0) if valid is None else validity_bitmap(valid)
    return pa.Array.from_buffers(type_, len(values), [bitmap, pa.py_buffer(data)], nulls)


def int_lists(values: list) -> pa.Array:
    """A list<int64> column from Python sequences of ints (None: null)."""
    lengths = [0 if v is None else len(v) for v in values]
    offsets = np.zeros(len(values) + 1, np.int32)
    np.cumsum(lengths, out=offsets[1:])
    flat = np.array([x for v in values if v is not None for x in v], np.int64)
    bitmap, nulls = validity_bitmap(np.array([v is not None for v in values], np.bool_))
    return pa.Array.from_buffers(
        pa.list_(pa.int64()), len(values), [bitmap, pa.py_buffer(offsets)], nulls,
        children=[numbers(flat, pa.int64())],
    )  # fmt: skip


def coded(words: Words, codes: np.ndarray, valid: np.ndarray | None = None) -> pa.Array:
    """`words[code]` per row; null where `valid` is false or the code is negative."""
    codes = np.ascontiguousarray(codes, np.int32)
    ok = codes >= 0 if valid is None else (codes >= 0) & valid.astype(np.bool_)
    data, offsets = words.expand(codes, ok.view(np.uint8))
    bitmap, nulls = validity_bitmap(ok)
    return pa.StringArray.from_buffers(
        len(codes), pa.py_buffer(offsets), pa.py_buffer(data), bitmap, nulls
    )


def text(buffers: tuple[memoryview, np.ndarray, np.ndarray]) -> pa.Array:
    """A string column from a TextVec's (data, offsets, validity), its buffers wrapped as
    they are."""
    data, offsets, valid = buffers
    bitmap, nulls = validity_bitmap(valid)
    return pa.StringArray.from_buffers(
        len(valid), pa.py_buffer(offsets), pa.py_buffer(data), bitmap, nulls
    )


def listed(offsets: np.ndarray, values: pa.Array) -> pa.Array:
    """A list column: element i holds values[offsets[i]:offsets[i + 1]]."""
    return pa.ListArray.from_arrays(numbers(offsets, pa.int32()), values)


def cost_column(
    prompt: np.ndarray, completion: np.ndarray, valid: np.ndarray, prices: Prices
) -> pa.Array:
    """`usage_cost` per row, as numpy computes it: the same IEEE operations in the same order
    as the reference's Python floats (each ufunc rounds once; no fused multiply-add), so the
    same bits. Null where no count was recorded, everywhere without a price."""
    if not prices.known:
        return pa.nulls(len(valid), pa.float64())
    # A count not recorded is 0 in its buffer, as `usage_cost` counts it.
    cost = (
        prompt.astype(np.float64) * (prices.prompt or 0.0)
        + completion.astype(np.float64) * (prices.completion or 0.0)
    ) / 1e6
    return numbers(cost, pa.float64(), valid)


def origin_codes(step_k: np.ndarray, step_ep: np.ndarray, continuations: list) -> np.ndarray:
    """The origin of each step (`usage.origin_of`, column by column): `prefix` before the
    episode's prefix length, `fix` at it when fixed, `agent` after (and in ordinary runs)."""
    prefix = np.array([c.prefix_steps if c is not None else 0 for c in continuations], np.int64)
    fixed = np.array([c is not None and c.fixed for c in continuations], np.bool_)
    if not len(step_k):
        return np.zeros(0, np.int32)
    p = prefix[step_ep]
    codes = np.full(len(step_k), _AGENT, np.int32)
    codes[(step_k == p) & fixed[step_ep]] = _FIX
    codes[step_k < p] = _PREFIX
    return codes


def tables(out, vocab, episodes: list, head: tuple[str, str, str], prices: Prices) -> tuple:
    """(steps, episodes, goals) tables of a replayed batch, and rows per episode."""
    # the kernel's own counts: the steps of each episode's log (either kind) and its goals
    step_counts = np.array(out.episodes["n_steps"][: len(episodes)], np.int64)
    goal_counts = np.array(out.episodes["n_goals"][: len(episodes)], np.int64)
    columns = _Columns(out, vocab, episodes, head)
    n, n_goals = int(step_counts.sum()), int(goal_counts.sum())
    return (
        _table(StepRow, columns.steps(n, prices)),
        _table(EpisodeRow, columns.episodes(prices)),
        _table(GoalRow, columns.goals(n_goals)),
        step_counts,
        goal_counts,
    )


class _Columns:
    """The columns of a batch's three tables, from the kernel's buffers (`out`) and the
    batch's vocabularies: the code columns of states, components and feedback texts are
    per batch, those of the episodes' ids, devices and categories per episode."""

    def __init__(self, out, vocab, episodes: list, head: tuple[str, str, str]) -> None:
        self.out = out
        self.inputs = episodes
        self.continuations = out.continuations
        self.states = Words(vocab.states)
        self.comps = Words(vocab.comps)
        self.texts = Words(vocab.texts)
        self.per_episode = {
            "episode_id": Words(out.episode_ids),
            "device_id": Words(out.device_ids),
            "category": Words(out.categories),
        }
        self.run = dict(
            zip(("run_id", "model", "agent_kind"), (Words([v]) for v in head), strict=True)
        )

    def head(self, episode_of: np.ndarray, rows: int) -> dict[str, pa.Array]:
        """The columns that open every row (`EpisodeKey`), for rows of episodes `episode_of`."""
        columns = {name: coded(w, np.zeros(rows, np.int32)) for name, w in self.run.items()}
        columns.update({name: coded(w, episode_of) for name, w in self.per_episode.items()})
        return columns

    def steps(self, n: int, prices: Prices) -> dict[str, pa.Array]:
        """The steps table's columns: what the step was and did, then how it is scored."""
        sv = {k: v[:n] for k, v in self.out.steps.items()}
        return {**self._step_actions(sv, n), **self._step_scores(sv, prices)}

    def _step_actions(self, sv: dict[str, np.ndarray], n: int) -> dict[str, pa.Array]:
        out, states, comps = self.out, self.states, self.comps
        scored = sv["scored"].astype(np.bool_)
        return {
            **self.head(sv["step_ep"], n),
            "step": numbers(sv["step_k"], pa.int64()),
            "goal_index": numbers(sv["goal_index"], pa.int64(), scored),
            "goal_state": coded(states, sv["goal_state"], scored),
            "view_before": coded(_VIEWS, sv["view_before"], scored),
            "view_after": coded(_VIEWS, sv["view_after"], scored),
            "dashboard_unlocked": numbers(sv["unlocked"], pa.bool_(), sv["unlocked_valid"]),
            "action_type": coded(_ACTIONS, sv["action_type"]),
            "action_raw": text(out.action_raw.buffers()),
            "thinking": text(out.thinking.buffers()),
            "output": text(out.output.buffers()),
            "x": numbers(sv["x"], pa.float64(), sv["has_coord"]),
            "y": numbers(sv["y"], pa.float64(), sv["has_coord"]),
            "params": listed(out.params_off.array(), text(out.params.buffers())),
            "parse_ok": numbers(sv["parse_ok"], pa.bool_()),
            "parse_detail": coded(_DETAILS, sv["parse_detail"]),
            "feedback_kind": coded(_KINDS, sv["kind"], scored),
            "feedback_text": coded(self.texts, sv["text"], scored),
            "state_before": coded(states, sv["state_before"], scored),
            "state_after": coded(states, sv["state_after"], scored),
            "states_entered": listed(out.entered_off.array(), coded(states, out.entered.array())),
            "transition_component": coded(comps, sv["tr_comp"], scored),
            "dangerous": numbers(sv["dangerous"], pa.bool_(), scored),
            "is_switch": numbers(sv["is_switch"], pa.bool_(), scored),
            "completed_goals": numbers(sv["completed"], pa.int64(), scored),
            "truncated": numbers(~scored, pa.bool_()),
            "recorded_feedback": text(out.rec_feedback.buffers()),
            "recorded_state": text(out.rec_state.buffers()),
            "recorded_view": text(out.rec_view.buffers()),
            "diverged": numbers(sv["diverged"], pa.bool_(), sv["diverged_valid"]),
            "diverged_fields": listed(
                out.div_off.array(), coded(_DIVERGENCE_FIELDS, out.div.array())
            ),
            "timestamp": numbers(sv["timestamp"], pa.float64(), sv["timestamp_valid"]),
        }

    def _step_scores(self, sv: dict[str, np.ndarray], prices: Prices) -> dict[str, pa.Array]:
        out, comps = self.out, self.comps
        scored = sv["scored"].astype(np.bool_)
        interaction = scored & sv["is_interaction"].astype(np.bool_)
        error_type = sv["error_type"]
        return {
            "is_interaction": numbers(sv["is_interaction"], pa.bool_(), scored),
            "hit_component": numbers(sv["hit_component"], pa.bool_(), interaction),
            "hit_target": numbers(sv["hit_target"], pa.bool_(), interaction),
            "hit_components": listed(out.hits_off.array(), coded(comps, out.hits.array())),
            "nearest_target": coded(comps, sv["nearest"], scored),
            "progress": numbers(sv["progress"], pa.bool_(), scored),
            "dist_before": numbers(
                sv["dist_before"], pa.int64(), scored & (sv["dist_before"] < INF)
            ),
            "dist_after": numbers(sv["dist_after"], pa.int64(), scored & (sv["dist_after"] < INF)),
            "error_type": coded(_ERROR_TYPES, error_type, scored),
            "error_detail": coded(_DETAILS, sv["error_detail"], scored),
            "error_group": coded(_ERROR_GROUPS, error_type, scored),
            "switch_class": coded(_SWITCH_CLASSES, sv["switch_class"], scored),
            "repetitive": numbers(sv["repetitive"], pa.bool_(), scored),
            "eer_valid": numbers(sv["eer_valid"], pa.bool_(), sv["eer_valid_valid"]),
            "distance": numbers(sv["distance"], pa.float64(), sv["distance_valid"]),
            "weight": numbers(sv["weight"], pa.int64(), sv["distance_valid"]),
            "budget_global_left": numbers(sv["budget_global_left"], pa.float64(), scored),
            "budget_local_left": numbers(sv["budget_local_left"], pa.float64(), scored),
            "prompt_tokens": numbers(sv["prompt"], pa.int64(), sv["prompt_valid"]),
            "completion_tokens": numbers(sv["completion"], pa.int64(), sv["completion_valid"]),
            "latency_s": numbers(sv["latency"], pa.float64(), sv["latency_valid"]),
            "cost_usd": cost_column(
                sv["prompt"], sv["completion"], sv["prompt_valid"] | sv["completion_valid"], prices
            ),
            "origin": coded(
                _ORIGINS, origin_codes(sv["step_k"], sv["step_ep"], self.continuations)
            ),
        }

    def episodes(self, prices: Prices) -> dict[str, pa.Array]:
        out, states, episodes = self.out, self.states, self.inputs
        n_eps = len(episodes)
        ev = {k: v[:n_eps] for k, v in out.episodes.items()}
        return {
            **self.head(np.arange(n_eps, dtype=np.int32), n_eps),
            "n_goals": numbers(ev["n_goals"], pa.int64()),
            "goals_completed": numbers(ev["goals_completed"], pa.int64()),
            "success": numbers(ev["success"], pa.bool_()),
            "termination": coded(_TERMINATIONS, ev["termination"]),
            "L_opt": numbers(ev["l_opt"], pa.int64()),
            "L_act": numbers(ev["l_act"], pa.int64()),
            "spl": numbers(ev["spl"], pa.float64()),
            "state_f1": numbers(ev["state_f1"], pa.float64()),
            "n_switches": numbers(ev["n_switches"], pa.int64()),
            "vsps_switches": numbers(ev["vsps_switches"], pa.int64()),
            "vsps": numbers(ev["vsps"], pa.float64(), ev["vsps_valid"]),
            "n_steps": numbers(ev["n_steps"], pa.int64()),
            "truncated_steps": numbers(ev["truncated"], pa.int64()),
            "diverged_steps": numbers(ev["diverged"], pa.int64()),
            "lambda": numbers(ev["lam"], pa.float64()),
            "budget_global": numbers(ev["budget_global"], pa.float64()),
            "initial_state": coded(states, ev["initial_state"]),
            "initial_view": coded(_VIEWS, ev["initial_view"]),
            "goals": listed(out.e_goals_off.array(), coded(states, out.e_goals.array())),
            "c_opt": listed(
                out.e_goals_off.array(),
                numbers(out.e_c_opt.array(), pa.int64()),
            ),
            "c_opt_stated": int_lists(out.c_opt_stated),
            "visited_states": listed(
                out.e_visited_off.array(), coded(states, out.e_visited.array())
            ),
            "optimal_states": listed(
                out.e_optimal_off.array(), coded(states, out.e_optimal.array())
            ),
            "prompt_tokens": numbers(ev["prompt"], pa.int64(), ev["prompt_valid"]),
            "completion_tokens": numbers(ev["completion"], pa.int64(), ev["completion_valid"]),
            "latency_s": numbers(ev["latency"], pa.float64(), ev["latency_valid"]),
            "cost_usd": cost_column(
                ev["prompt"], ev["completion"], ev["prompt_valid"] | ev["completion_valid"], prices
            ),
            **continuation_columns(self.continuations),
        }

    def goals(self, n_goals: int) -> dict[str, pa.Array]:
        out, episodes = self.out, self.inputs
        ev_n_goals = out.episodes["n_goals"][: len(episodes)]
        gv = {k: v[:n_goals] for k, v in out.goals.items()}
        return {
            **self.head(gv["episode"], n_goals),
            "n_goals": numbers(ev_n_goals[gv["episode"]], pa.int64()),
            "goal_index": numbers(gv["index"], pa.int64()),
            "goal_state": coded(self.states, gv["state"]),
            "instruction": py_column(out.instructions, pa.string()),
            "c_opt": numbers(gv["c_opt"], pa.int64()),
            "c_opt_dyn": numbers(gv["dyn"], pa.int64(), gv["dyn_valid"]),
            "reached": numbers(gv["reached"], pa.bool_()),
            "completed": numbers(gv["completed"], pa.bool_()),
            "started_step": numbers(gv["started"], pa.int64(), gv["started"] >= 0),
            "completed_step": numbers(gv["completed_step"], pa.int64(), gv["completed_step"] >= 0),
            "steps_used": numbers(gv["steps_used"], pa.int64()),
            "switches": numbers(gv["switches"], pa.int64()),
            "perfect": numbers(gv["perfect"], pa.bool_()),
        }


def continuation_columns(continuations: list) -> dict[str, pa.Array]:
    """The episodes' continuation columns (null in ordinary runs), from their log lines: one
    per field of `Continuation`, typed as the episode row declares it."""
    schema = arrow_schema(EpisodeRow)
    names = Continuation.__struct_fields__
    if all(c is None for c in continuations):  # an ordinary run: no `pa.array`, no pandas
        return {name: pa.nulls(len(continuations), schema.field(name).type) for name in names}
    return {
        name: pa.array(
            [None if c is None else getattr(c, name) for c in continuations],
            schema.field(name).type,
        )
        for name in names
    }


def _table(row_type: type, columns: dict[str, pa.Array]) -> pa.Table:
    schema = arrow_schema(row_type)
    return pa.Table.from_arrays([columns[f.name] for f in schema], schema=schema)
