"""The steps table of a columnar batch: every StepRow column from the parse, the loop's
records and the classification, built from numpy arrays and integer codes (one Arrow
`take` per string column)."""

from __future__ import annotations

import numpy as np
import pyarrow as pa
import pyarrow.compute as pc

from ..semantics._episode import timestamp_seconds
from ..semantics._plan import INF
from ..semantics._records import LogStep
from ..semantics._rows import StepRow
from ..semantics._tables import arrow_schema
from ..semantics._vocab import ERROR_GROUPS, ERROR_TYPES, FEEDBACK_KINDS, SWITCH_CLASSES, VIEW_ORDER
from . import _columnar_arrow as arw
from ._columnar_classify import Classified, Scored
from ._columnar_parse import ParsedSteps
from ._columnar_tables import ColumnarCache, MachineTables

_DIVERGENCE_FIELDS = pa.array(["feedback", "state", "view"], pa.string())
_FEEDBACK_KINDS = pa.array(FEEDBACK_KINDS, pa.string())
_VIEWS = pa.array(VIEW_ORDER, pa.string())
_ERROR_TYPES = pa.array(ERROR_TYPES, pa.string())
_ERROR_GROUPS = pa.array([ERROR_GROUPS[t] for t in ERROR_TYPES], pa.string())
_SWITCH_CLASSES = pa.array(SWITCH_CLASSES, pa.string())
_NO_STRINGS = pa.scalar([], pa.list_(pa.string()))


def step_table(
    cache: ColumnarCache,
    episodes: list,
    steps: list[LogStep],
    parsed: ParsedSteps,
    step_ep: np.ndarray,
    step_k: np.ndarray,
    scored: np.ndarray,
    sc: Scored,
    cl: Classified,
    head: tuple[str, str, str],
    unlocked: np.ndarray,
    b_local: np.ndarray,
    budget_global: np.ndarray,
    mts: list[MachineTables],
) -> tuple[pa.Table, np.ndarray]:
    """The steps table (every StepRow column), and the diverged steps per episode."""
    n = len(step_ep)
    actions, outcomes = cache.actions, cache.outcomes
    live = np.zeros(n, np.bool_)
    live[scored] = True

    def full(values: np.ndarray, fill: object = 0) -> np.ndarray:
        return arw.scatter(n, scored, values, fill)

    def opt(values: np.ndarray, type_: pa.DataType, valid: np.ndarray | None = None):
        fill = False if type_ == pa.bool_() else 0
        return arw.numbers(full(values, fill), type_, live if valid is None else full(valid, False))

    def codes(values: np.ndarray) -> np.ndarray:
        return full(values, -1)

    def per_episode(values: list) -> pa.Array:
        return pa.array(values, pa.string()).take(pa.array(step_ep))

    goal_names = [e.machine.states[g] for e in episodes for g in e.setup.goals]
    goal_start = np.cumsum([0] + [len(e.setup.goals) for e in episodes])[:-1]
    state_base = np.array([mt.state_base for mt in mts], np.int64)[sc.machine]
    has_dashboard = np.array([mt.has_dashboard for mt in mts], np.bool_)[sc.machine]
    oc = codes(sc.outcome)
    kinds = outcomes.cols["kind"][sc.outcome].astype(np.int64)

    feedback_kind = _FEEDBACK_KINDS.take(pa.array(codes(kinds), mask=~live))
    feedback_text = cache.text_array.take(oc)
    state_after = cache.state_array.take(codes(state_base + sc.s1))
    view_after = _VIEWS.take(pa.array(codes(sc.v1), mask=~live))
    recorded_feedback = pa.array([s.feedback for s in steps], pa.string())
    recorded_state = pa.array([s.state for s in steps], pa.string())
    recorded_view = pa.array([s.view for s in steps], pa.string())
    diverged, diverged_counts, diverged_values, diverged_steps = _divergence(
        live, step_ep, len(episodes), recorded_feedback, recorded_state, recorded_view,
        feedback_kind, feedback_text, state_after, view_after,
    )  # fmt: skip
    hit_counts = full(np.diff(cl.hit_offsets))
    error_type = codes(cl.error_type)
    columns = {
        "run_id": pa.array([head[0]], pa.string()).take(pa.array(np.zeros(n, np.int64))),
        "model": pa.array([head[1]], pa.string()).take(pa.array(np.zeros(n, np.int64))),
        "agent_kind": pa.array([head[2]], pa.string()).take(pa.array(np.zeros(n, np.int64))),
        "episode_id": per_episode([e.task.episode_id for e in episodes]),
        "device_id": per_episode([e.machine.device_id for e in episodes]),
        "category": per_episode([e.machine.category for e in episodes]),
        "step": pa.array(step_k, pa.int64()),
        "goal_index": opt(sc.goal_index, pa.int64()),
        "goal_state": pa.array(goal_names, pa.string()).take(
            pa.array(codes(goal_start[sc.ep] + sc.goal_index), mask=~live)
        ),
        "view_before": _VIEWS.take(pa.array(codes(sc.v0), mask=~live)),
        "view_after": view_after,
        "dashboard_unlocked": opt(unlocked, pa.bool_(), has_dashboard),
        "action_type": cache.action_type_array.take(parsed.aid),
        "action_raw": parsed.action_raw,
        "thinking": parsed.thinking,
        "output": parsed.output,
        "x": arw.numbers(parsed.x, pa.float64(), parsed.has_coord),
        "y": arw.numbers(parsed.y, pa.float64(), parsed.has_coord),
        "params": cache.params_array.take(parsed.aid),
        "parse_ok": pa.array(actions.cols["tcode"][parsed.aid] >= 0, pa.bool_()),
        "parse_detail": cache.detail_array.take(actions.cols["detail"][parsed.aid]),
        "feedback_kind": feedback_kind,
        "feedback_text": feedback_text,
        "state_before": cache.state_array.take(codes(state_base + sc.s0)),
        "state_after": state_after,
        "states_entered": pc.fill_null(cache.entered_array.take(oc), _NO_STRINGS),
        "transition_component": cache.component_array.take(oc),
        "dangerous": opt(outcomes.cols["dangerous"][sc.outcome], pa.bool_()),
        "is_switch": opt(outcomes.cols["switched"][sc.outcome], pa.bool_()),
        "completed_goals": opt(sc.completed, pa.int64()),
        "is_interaction": opt(cl.is_interaction, pa.bool_()),
        "hit_component": opt(cl.hit_component, pa.bool_(), cl.is_interaction),
        "hit_target": opt(cl.hit_target, pa.bool_(), cl.is_interaction),
        "hit_components": arw.ragged_strings(hit_counts, cache.comp_array.take(cl.hit_values)),
        "nearest_target": cache.comp_array.take(codes(cl.nearest)),
        "progress": opt(cl.progress, pa.bool_()),
        "dist_before": opt(cl.dist_before, pa.int64(), cl.dist_before < INF),
        "dist_after": opt(cl.dist_after, pa.int64(), cl.dist_after < INF),
        "error_type": _ERROR_TYPES.take(pa.array(error_type, mask=error_type < 0)),
        "error_detail": cache.detail_array.take(full(cl.error_detail)),
        "error_group": _ERROR_GROUPS.take(pa.array(error_type, mask=error_type < 0)),
        "switch_class": _SWITCH_CLASSES.take(
            pa.array(codes(cl.switch_class), mask=codes(cl.switch_class) < 0)
        ),
        "repetitive": opt(cl.repetitive, pa.bool_()),
        "eer_valid": opt(cl.eer_valid, pa.bool_(), ~cl.is_switch_view),
        "distance": opt(cl.distance, pa.float64(), ~np.isnan(cl.distance)),
        "weight": opt(cl.weight, pa.int64(), cl.weight > 0),
        "budget_global_left": opt(budget_global[sc.ep] - (step_k[scored] + 1), pa.float64()),
        "budget_local_left": opt(b_local.astype(np.float64), pa.float64()),
        "truncated": pa.array(~live, pa.bool_()),
        "recorded_feedback": recorded_feedback,
        "recorded_state": recorded_state,
        "recorded_view": recorded_view,
        "diverged": diverged,
        "diverged_fields": arw.ragged_strings(diverged_counts, diverged_values),
        "timestamp": _timestamps([s.timestamp for s in steps]),
    }
    schema = arrow_schema(StepRow)
    return pa.Table.from_arrays([columns[f.name] for f in schema], schema=schema), diverged_steps


def _divergence(
    live: np.ndarray,
    step_ep: np.ndarray,
    n_eps: int,
    recorded_feedback: pa.Array,
    recorded_state: pa.Array,
    recorded_view: pa.Array,
    feedback_kind: pa.Array,
    feedback_text: pa.Array,
    state_after: pa.Array,
    view_after: pa.Array,
) -> tuple[pa.Array, np.ndarray, pa.Array, np.ndarray]:
    """Divergence (PROTOCOL §7.2) on scored steps: (diverged, field counts, field names,
    diverged steps per episode)."""

    def differs(recorded: pa.Array, mine: pa.Array) -> np.ndarray:
        return pc.fill_null(pc.not_equal(recorded, mine), False).to_numpy(zero_copy_only=False)

    is_kind = pc.is_in(recorded_feedback, pa.array(FEEDBACK_KINDS, pa.string()))
    mine = pc.if_else(pc.fill_null(is_kind, False), feedback_kind, feedback_text)
    lowered = _lower(recorded_view)
    fields = np.stack(
        [
            differs(recorded_feedback, mine),
            differs(recorded_state, state_after),
            differs(lowered, view_after),
        ],
        axis=1,
    )
    fields &= live[:, None]
    recorded = (
        recorded_feedback.is_valid().to_numpy(zero_copy_only=False)
        | recorded_state.is_valid().to_numpy(zero_copy_only=False)
        | recorded_view.is_valid().to_numpy(zero_copy_only=False)
    ) & live
    counts = fields.sum(axis=1)
    flat = np.flatnonzero(fields.ravel()) % 3
    diverged = counts > 0
    per_episode = np.bincount(step_ep, weights=diverged, minlength=n_eps).astype(np.int64)
    return (
        arw.numbers(diverged, pa.bool_(), recorded),
        counts,
        _DIVERGENCE_FIELDS.take(pa.array(flat, pa.int64())),
        per_episode,
    )


def _lower(values: pa.Array) -> pa.Array:
    """Python's `str.lower()` of each string (on the distinct values only)."""
    encoded = pc.dictionary_encode(values)
    lowered = pa.array(
        [v.lower() if v is not None else None for v in encoded.dictionary.to_pylist()],
        pa.string(),
    )
    return lowered.take(encoded.indices)


def _timestamps(values: list) -> pa.Array:
    """`timestamp_seconds` of each recorded timestamp (numbers pass as they are)."""
    try:
        return pa.array(values, pa.float64())
    except (pa.ArrowInvalid, pa.ArrowTypeError):
        return pa.array([timestamp_seconds(v) for v in values], pa.float64())
