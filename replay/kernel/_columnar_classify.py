"""PROTOCOL §5 classification of a batch of scored steps with array operations.

The same rules as `Classifier.classify`, column by column: hits are point-in-rect tests of
each step against its machine's component rects in its view (one row per (step, rect)
pair), targets and distances the same against the target rects of (state, goal, view),
weights a running count per (episode, goal, nearest target), repetition the first
occurrence of a key per (episode, goal, state). The one rule that needs the transitions
themselves (which error a target hit without progress is) calls the scalar classifier for
those few steps.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..semantics._classify import Classifier
from ..semantics._vocab import (
    ERROR_TYPES,
    FB_INVALID,
    FB_TRANSITION,
    FB_UNLOCKED,
    FB_WAIT_NO_EFFECT,
    SWITCH_CLASSES,
    VIEW_ORDER,
)
from ._columnar_arrow import ragged_rows
from ._columnar_tables import (
    INTERACTABLE,
    KIND_CODES,
    N_INTERACTIONS,
    N_VIEWS,
    T_SWITCH,
    T_WAIT,
    ColumnarCache,
    MachineTables,
)

ERROR_CODES = {name: i for i, name in enumerate(ERROR_TYPES)}
SWITCH_CODES = {name: i for i, name in enumerate(SWITCH_CLASSES)}
_CLASS_OF_BITS = np.array([SWITCH_CODES[c] for c in ("NN", "NP", "PN", "PP")])
_K_INVALID = KIND_CODES[FB_INVALID]
_K_UNLOCKED = KIND_CODES[FB_UNLOCKED]
_K_TRANSITION = KIND_CODES[FB_TRANSITION]
_K_WAIT_NO_EFFECT = KIND_CODES[FB_WAIT_NO_EFFECT]


@dataclass
class Scored:
    """The scored steps of a batch, in order, as arrays (one element per step)."""

    ep: np.ndarray  # episode index in the batch
    machine: np.ndarray  # index into the batch's machine list
    goal_index: np.ndarray
    goal: np.ndarray  # goal state
    dist_base: np.ndarray  # goal block rows (MachineTables.goal_block)
    trect_base: np.ndarray
    s0: np.ndarray
    s1: np.ndarray
    v0: np.ndarray
    v1: np.ndarray
    outcome: np.ndarray
    completed: np.ndarray
    aid: np.ndarray
    x: np.ndarray
    y: np.ndarray
    has_coord: np.ndarray
    point: np.ndarray  # the point key (`_columnar_sim.step_keys`)


@dataclass
class Classified:
    """CLASSIFICATION_FIELDS as arrays over the scored steps (+ validity where nullable)."""

    is_interaction: np.ndarray
    hit_component: np.ndarray  # valid where is_interaction
    hit_target: np.ndarray  # valid where is_interaction
    hit_offsets: np.ndarray  # hit_components: list offsets (len n + 1) into hit_values
    hit_values: np.ndarray  # global component ids
    nearest: np.ndarray  # global component id, -1 = null
    progress: np.ndarray
    dist_before: np.ndarray  # INF = null
    dist_after: np.ndarray
    error_type: np.ndarray  # ERROR_TYPES index, -1 = null
    error_detail: np.ndarray  # cache.details code, 0 = null
    switch_class: np.ndarray  # SWITCH_CLASSES index, -1 = null
    repetitive: np.ndarray
    eer_valid: np.ndarray  # valid where not a switch_view step
    is_switch_view: np.ndarray
    distance: np.ndarray  # NaN = null
    weight: np.ndarray  # 0 = null


def _python_max3(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """`max(a, 0.0, b)` with Python's rule (the first of equal values wins, so signs of
    zero match `rect_distance`)."""
    m = np.where(a < 0.0, 0.0, a)
    return np.where(b > m, b, m)


def classify(cache: ColumnarCache, mts: list[MachineTables], sc: Scored) -> Classified:
    n = len(sc.ep)
    actions, outcomes = cache.actions, cache.outcomes
    tcode = actions.cols["tcode"][sc.aid]
    ok = tcode >= 0
    kind = outcomes.cols["kind"][sc.outcome]
    switched = outcomes.cols["switched"][sc.outcome]
    dist = cache.dist["dist"]
    d_before = dist[sc.dist_base + sc.s0]
    d_after = dist[sc.dist_base + sc.s1]
    progress = (sc.completed > 0) | (d_after < d_before)
    interaction_type = ok & (tcode < N_INTERACTIONS)
    is_interaction = interaction_type & sc.has_coord & INTERACTABLE[sc.v0] & (kind != _K_UNLOCKED)
    gids = np.array([mt.gid for mt in mts], np.int64)[sc.machine]

    # Hits: component rects of the step's machine in its view (any state).
    hit_steps = np.flatnonzero(ok & sc.has_coord & (tcode != T_SWITCH))
    crow = gids[hit_steps] * N_VIEWS + sc.v0[hit_steps]
    owner, rect = ragged_rows(cache.crect["start"][crow], cache.crect["count"][crow])
    r = cache.comp_rects
    px, py = sc.x[hit_steps][owner], sc.y[hit_steps][owner]
    inside = (r["x0"][rect] <= px) & (px <= r["x1"][rect])
    inside &= (r["y0"][rect] <= py) & (py <= r["y1"][rect])
    hit_of, hit_comp = hit_steps[owner[inside]], r["comp"][rect[inside]]
    if len(hit_of):  # rects are sorted by component: drop repeats of a component
        fresh = np.ones(len(hit_of), np.bool_)
        fresh[1:] = (hit_of[1:] != hit_of[:-1]) | (hit_comp[1:] != hit_comp[:-1])
        hit_of, hit_comp = hit_of[fresh], hit_comp[fresh]
    n_hits = np.bincount(hit_of, minlength=n)
    hit_offsets = np.zeros(n + 1, np.int64)
    np.cumsum(n_hits, out=hit_offsets[1:])
    comp_base = np.array([mt.comp_base for mt in mts], np.int64)[sc.machine]
    hit_mask = np.zeros(n, np.int64)
    np.bitwise_or.at(hit_mask, hit_of, np.int64(1) << (hit_comp - comp_base[hit_of]))
    has_hits = n_hits > 0

    # Targets of interactions: distance, nearest, hit_target, weight.
    nearest = np.full(n, -1, np.int64)
    distance = np.full(n, np.nan)
    hit_target = np.zeros(n, np.bool_)
    inter = np.flatnonzero(is_interaction)
    trow = sc.trect_base[inter] + sc.s0[inter] * N_VIEWS + sc.v0[inter]
    _fill_targets(cache, mts, sc, inter, trow)
    owner, rect = ragged_rows(cache.trect["start"][trow], cache.trect["count"][trow])
    if len(owner):
        t = cache.target_rects
        step_of = inter[owner]
        px, py = sc.x[step_of], sc.y[step_of]
        dx = _python_max3(t["x0"][rect] - px, px - t["x1"][rect])
        dy = _python_max3(t["y0"][rect] - py, py - t["y1"][rect])
        d = np.where(dx == 0.0, dy, dx)
        both = np.flatnonzero((dx != 0.0) & (dy != 0.0))
        if len(both):  # `(dx * dx + dy * dy) ** 0.5` exactly as Python computes it
            sq = (dx[both] * dx[both] + dy[both] * dy[both]).tolist()
            d[both] = [v**0.5 for v in sq]
        comp = t["comp"][rect]
        order = np.lexsort((comp, d, owner))
        first = np.ones(len(order), np.bool_)
        first[1:] = owner[order[1:]] != owner[order[:-1]]
        best = order[first]
        nearest[step_of[best]] = comp[best]
        distance[step_of[best]] = d[best]
        hit_target[step_of[d == 0.0]] = True
    weight = _weights(sc, nearest, progress)

    # Error types (PROTOCOL §5 table, in `Classifier.classify`'s order).
    error_type = np.full(n, -1, np.int64)
    error_detail = np.zeros(n, np.int64)
    codes = cache.details.code
    is_switch_view = tcode == T_SWITCH
    failed = ~ok
    error_type[failed] = ERROR_CODES["action_error"]
    error_detail[failed] = actions.cols["detail"][sc.aid[failed]]
    outcome_detail = outcomes.cols["detail"][sc.outcome]
    bad_switch = is_switch_view & ~switched
    error_type[bad_switch] = ERROR_CODES["action_error"]
    error_detail[bad_switch] = outcome_detail[bad_switch]
    switch_class = _switch_classes(cache, mts, sc, is_switch_view & switched)
    error_type[switch_class == SWITCH_CODES["NN"]] = ERROR_CODES["switch_view_nn"]
    error_type[switch_class == SWITCH_CODES["PN"]] = ERROR_CODES["switch_view_pn"]
    idle = (tcode == T_WAIT) & (kind == _K_WAIT_NO_EFFECT)
    error_type[idle] = ERROR_CODES["invalid_waiting"]
    error_detail[idle] = codes("no_effect")
    invalid = interaction_type & (kind == _K_INVALID)
    out_of_range = invalid & (outcome_detail == codes("out_of_range"))
    error_type[invalid] = ERROR_CODES["action_error"]
    error_detail[invalid] = outcome_detail[invalid]
    error_type[out_of_range] = ERROR_CODES["invalid_coord"]
    missed = interaction_type & (kind != _K_INVALID) & (kind != _K_UNLOCKED) & ~progress
    error_type[missed & ~has_hits] = ERROR_CODES["invalid_coord"]
    error_type[missed & has_hits & ~hit_target] = ERROR_CODES["component_selection"]
    for i in np.flatnonzero(missed & has_hits & hit_target).tolist():
        error_type[i], error_detail[i] = _target_miss(cache, mts[sc.machine[i]], sc, i)

    repetitive = _repetitive(sc, ok & ~is_switch_view, tcode, has_hits, hit_mask)
    dangerous = outcomes.cols["dangerous"][sc.outcome]
    eer = (kind == _K_TRANSITION) | outcomes.cols["unlocked_now"][sc.outcome]
    eer_valid = ok & eer & ~dangerous & ~repetitive
    return Classified(
        is_interaction=is_interaction,
        hit_component=has_hits,
        hit_target=hit_target,
        hit_offsets=hit_offsets,
        hit_values=hit_comp,
        nearest=nearest,
        progress=progress,
        dist_before=d_before,
        dist_after=d_after,
        error_type=error_type,
        error_detail=error_detail,
        switch_class=switch_class,
        repetitive=repetitive,
        eer_valid=eer_valid,
        is_switch_view=is_switch_view,
        distance=distance,
        weight=weight,
    )


def _target_miss(cache: ColumnarCache, mt: MachineTables, sc: Scored, i: int) -> tuple[int, int]:
    """(error type, detail code) of an interaction on a target without progress, by the
    scalar classifier; it reads the transitions of (state, goal) whose rects in the view
    hold the point, so it is memoised on (state, goal, view, action, rects holding it)."""
    s0, goal, view, aid = int(sc.s0[i]), int(sc.goal[i]), int(sc.v0[i]), int(sc.aid[i])
    key = (s0, goal, view, aid, int(sc.point[i]) & mt.view_bits[view])
    got = mt.target_misses.get(key)
    if got is None:
        action = cache.actions.parsed(aid, float(sc.x[i]), float(sc.y[i]), True).action
        name, detail = Classifier(mt.machine)._interaction_error(
            s0, goal, VIEW_ORDER[view], action, [True], True
        )
        got = mt.target_misses[key] = (ERROR_CODES[name], cache.details.code(detail))
    return got


def _fill_targets(
    cache: ColumnarCache,
    mts: list[MachineTables],
    sc: Scored,
    steps: np.ndarray,
    rows: np.ndarray,
) -> None:
    """Compute the target rects of the (state, goal, view) rows not met before."""
    missing = np.flatnonzero(cache.trect["start"][rows] < 0)
    if not len(missing):
        return
    _, first = np.unique(rows[missing], return_index=True)
    for j in missing[first].tolist():
        i = steps[j]
        mt = mts[sc.machine[i]]
        gb = mt.goal_block(cache, int(sc.goal[i]))
        mt.fill_targets(cache, gb, int(sc.s0[i]), int(sc.v0[i]))


def _switch_classes(
    cache: ColumnarCache, mts: list[MachineTables], sc: Scored, switched: np.ndarray
) -> np.ndarray:
    """SWITCH_CLASSES index per step (-1 = null): P/N for the start and end views."""
    out = np.full(len(sc.ep), -1, np.int64)
    steps = np.flatnonzero(switched)
    if not len(steps):
        return out
    rows = sc.dist_base[steps] + sc.s0[steps]
    masks = cache.dist["swmask"]
    missing = np.flatnonzero(masks[rows] == -2)
    if len(missing):
        _, first = np.unique(rows[missing], return_index=True)
        for j in missing[first].tolist():
            i = steps[j]
            mt = mts[sc.machine[i]]
            mt.fill_switch_mask(cache, mt.goal_block(cache, int(sc.goal[i])), int(sc.s0[i]))
    mask = masks[rows]
    p0 = (mask >> sc.v0[steps]) & 1
    p1 = (mask >> sc.v1[steps]) & 1
    out[steps] = np.where(mask < 0, -1, _CLASS_OF_BITS[p0 * 2 + p1])
    return out


def _weights(sc: Scored, nearest: np.ndarray, progress: np.ndarray) -> np.ndarray:
    """1 + earlier non-progress interactions of the same (episode, goal) whose nearest
    target was the same component; 0 where there is no nearest target."""
    weight = np.zeros(len(nearest), np.int64)
    steps = np.flatnonzero(nearest >= 0)
    if not len(steps):
        return weight
    order = steps[np.lexsort((steps, nearest[steps], sc.goal_index[steps], sc.ep[steps]))]
    key_changed = np.ones(len(order), np.bool_)
    key_changed[1:] = (
        (sc.ep[order[1:]] != sc.ep[order[:-1]])
        | (sc.goal_index[order[1:]] != sc.goal_index[order[:-1]])
        | (nearest[order[1:]] != nearest[order[:-1]])
    )
    failed = (~progress[order]).astype(np.int64)
    before = np.cumsum(failed) - failed  # failures before each step, over all groups
    group_start = np.maximum.accumulate(np.where(key_changed, np.arange(len(order)), 0))
    weight[order] = 1 + before - before[group_start]
    return weight


def _repetitive(
    sc: Scored, candidate: np.ndarray, tcode: np.ndarray, has_hits: np.ndarray, hit_mask
) -> np.ndarray:
    """A non-switch step whose key (action, hit components or the point on a 10-unit grid,
    params, view) appeared before in the same episode, goal and state."""
    out = np.zeros(len(sc.ep), np.bool_)
    steps = np.flatnonzero(candidate)
    if not len(steps):
        return out
    has_coord = sc.has_coord[steps]
    hits = has_hits[steps]
    where = np.where(has_coord, np.where(hits, 1, 2), 0)
    mask = np.where(hits, hit_mask[steps], 0)
    point = has_coord & ~hits
    gx = np.where(point, np.floor(sc.x[steps] / 10 + 0.5), 0.0)
    gy = np.where(point, np.floor(sc.y[steps] / 10 + 0.5), 0.0)
    keys = (
        sc.ep[steps],
        sc.goal_index[steps],
        sc.s0[steps],
        sc.aid[steps],
        sc.v0[steps],
        where,
        mask,
        gx,
        gy,
    )
    order = np.lexsort((steps,) + keys[::-1])
    same = np.ones(len(order) - 1, np.bool_)
    for k in keys:
        ko = k[order]
        same &= ko[1:] == ko[:-1]
    repeated = np.zeros(len(order), np.bool_)
    repeated[1:] = same
    out[steps[order]] = repeated
    return out
