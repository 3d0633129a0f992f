"""Output rows (PROTOCOL §7): one class per table grain, each column documented.

These classes are the single declaration of the Parquet columns: the writer derives the
Arrow schema from them (`replay._tables`) and `schemas/*.schema.json` is generated from
them. Column names follow PROTOCOL §7 exactly.
"""

from __future__ import annotations

from typing import Annotated

import msgspec
from msgspec import Meta

OptStr = str | None
OptBool = bool | None
OptInt = int | None
OptFloat = float | None


def _d(text: str) -> Meta:
    return Meta(description=text)


class EpisodeKey(msgspec.Struct):
    """The columns that open every row: which run, and which episode of which device. Each
    row class below inherits them, so they come first, in this order, in every table."""

    run_id: Annotated[str, _d("Run identifier")]
    model: Annotated[str, _d("Model name from run.json")]
    agent_kind: Annotated[str, _d("vlm, human or scripted")]
    episode_id: Annotated[str, _d("Episode identifier")]
    device_id: Annotated[str, _d("Device identifier")]
    category: Annotated[str, _d("Device category")]


class StepRow(EpisodeKey):
    """One logged step (truncated steps included, flagged).

    Positional construction follows the field order below; the replay loop builds rows as
    tuples in this order (see `_episode.py`), and `CLASSIFICATION_FIELDS` is the contiguous
    block the classifier fills.
    """

    # The order starts with EpisodeKey's six fields. (The docstring above is part of the JSON
    # schema each MCAP file carries: editing it changes the MCAP bytes.)

    step: Annotated[int, _d("Step number, from 0 in log order")]
    goal_index: Annotated[
        OptInt, _d("Goal current at the start of the step (0-based); null if truncated")
    ]
    goal_state: Annotated[OptStr, _d("That goal's state")]
    view_before: Annotated[OptStr, _d("View at the start of the step")]
    view_after: Annotated[OptStr, _d("View after the step")]
    dashboard_unlocked: Annotated[OptBool, _d("Dashboard unlocked after the step")]
    action_type: Annotated[OptStr, _d("Lowercase action name; null on parse failure")]
    action_raw: Annotated[str, _d("Text of the Action entry (or the structured action)")]
    thinking: Annotated[OptStr, _d("The model's Thinking text")]
    output: Annotated[OptStr, _d("The full raw model output (null for structured actions)")]
    x: Annotated[OptFloat, _d("Click x on the 0..1000 scale")]
    y: Annotated[OptFloat, _d("Click y on the 0..1000 scale")]
    params: Annotated[list[str], _d("Normalised action parameters")]
    parse_ok: Annotated[bool, _d("The action parsed")]
    parse_detail: Annotated[OptStr, _d("no_action, multiple_actions, unknown_action or malformed")]
    feedback_kind: Annotated[OptStr, _d("PROTOCOL §3 feedback kind; null if truncated")]
    feedback_text: Annotated[OptStr, _d("Feedback text shown to the agent")]
    state_before: Annotated[OptStr, _d("Device state at the start of the step")]
    state_after: Annotated[OptStr, _d("Device state after the step (after immediate chains)")]
    states_entered: Annotated[list[str], _d("States entered by the step, transient ones included")]
    transition_component: Annotated[OptStr, _d("Component whose transition fired")]
    dangerous: Annotated[OptBool, _d("The step entered an error state")]
    is_switch: Annotated[OptBool, _d("A successful Switch_view")]
    completed_goals: Annotated[OptInt, _d("Goals completed by this step")]
    is_interaction: Annotated[OptBool, _d("Counts in the EIR/TIR denominator (PROTOCOL §5)")]
    hit_component: Annotated[OptBool, _d("Interaction inside a bbox of any component (any state)")]
    hit_target: Annotated[OptBool, _d("Interaction inside a bbox of a target component")]
    hit_components: Annotated[
        list[str], _d("Components whose bbox in the current view holds the point")
    ]
    nearest_target: Annotated[OptStr, _d("Target component nearest to the click")]
    progress: Annotated[OptBool, _d("Completed a goal or lowered dist(state, current goal)")]
    dist_before: Annotated[OptInt, _d("dist(state_before, current goal)")]
    dist_after: Annotated[OptInt, _d("dist(state_after, that goal)")]
    error_type: Annotated[OptStr, _d("PROTOCOL §5 error type, null for progress and neutral steps")]
    error_detail: Annotated[OptStr, _d("Detail code of the error")]
    error_group: Annotated[OptStr, _d("grounding, execution or navigation")]
    switch_class: Annotated[OptStr, _d("NP, PN, NN or PP for successful switches")]
    repetitive: Annotated[OptBool, _d("Repeats an earlier step of the same goal in the same state")]
    eer_valid: Annotated[OptBool, _d("Valid operation for EER; null for Switch_view steps")]
    distance: Annotated[
        OptFloat, _d("Distance from the click to the nearest target bbox (0..1000 scale)")
    ]
    weight: Annotated[
        OptInt, _d("1 + earlier failed interactions of the goal on the same nearest target")
    ]
    budget_global_left: Annotated[OptFloat, _d("B_global minus steps taken, after the step")]
    budget_local_left: Annotated[OptFloat, _d("B_local after the step")]
    truncated: Annotated[bool, _d("Logged after the episode terminated: not scored")]
    recorded_feedback: Annotated[OptStr, _d("Feedback the log recorded")]
    recorded_state: Annotated[OptStr, _d("State the log recorded")]
    recorded_view: Annotated[OptStr, _d("View the log recorded")]
    diverged: Annotated[
        OptBool, _d("A recorded value differs from the replay; null if none recorded")
    ]
    diverged_fields: Annotated[list[str], _d("Which of feedback, state, view differ")]
    timestamp: Annotated[OptFloat, _d("Recorded time of the step, seconds since the epoch")]
    prompt_tokens: Annotated[OptInt, _d("Prompt tokens the log recorded for the step")]
    completion_tokens: Annotated[OptInt, _d("Completion tokens the log recorded")]
    latency_s: Annotated[OptFloat, _d("Seconds the model took to answer (the log's latency)")]
    cost_usd: Annotated[OptFloat, _d("USD from the tokens and the run's prices; null without both")]
    origin: Annotated[
        str, _d("prefix (repeated from the source run), fix (the planner's) or agent")
    ]


class EpisodeRow(EpisodeKey, kw_only=True):
    """One replayed episode."""

    n_goals: Annotated[int, _d("Number of goals")]
    goals_completed: Annotated[int, _d("Goals completed")]
    success: Annotated[bool, _d("All goals completed")]
    termination: Annotated[
        str, _d("success, budget_global, budget_local, log_ended or context_exceeded")
    ]
    L_opt: Annotated[int, _d("sum of C_opt over goals")]
    L_act: Annotated[int, _d("Scored steps")]
    spl: Annotated[float, _d("S * L_opt / max(L_act, L_opt); S if L_opt = 0")]
    state_f1: Annotated[float, _d("F1 of visited states against the optimal path's states")]
    n_switches: Annotated[int, _d("Successful Switch_view steps (scored)")]
    vsps_switches: Annotated[int, _d("Switches taken while goals that were completed were current")]
    vsps: Annotated[OptFloat, _d("vsps_switches / goals_completed; null with no completed goal")]
    n_steps: Annotated[int, _d("Steps in the log")]
    truncated_steps: Annotated[int, _d("Logged steps after termination")]
    diverged_steps: Annotated[int, _d("Scored steps whose recorded values differ from the replay")]
    lam: Annotated[float, _d("lambda used for the budgets")] = msgspec.field(name="lambda")
    budget_global: Annotated[float, _d("B_global = lambda * L_opt")]
    initial_state: Annotated[str, _d("State at reset")]
    initial_view: Annotated[str, _d("View at reset")]
    goals: Annotated[list[str], _d("Goal states in order")]
    c_opt: Annotated[list[int], _d("C_opt per goal (computed)")]
    c_opt_stated: Annotated[list[int] | None, _d("C_opt the task stated, if any")]
    visited_states: Annotated[
        list[str], _d("States visited (reset and entered), first-visit order")
    ]
    optimal_states: Annotated[list[str], _d("States of the optimal path, first-visit order")]
    prompt_tokens: Annotated[OptInt, _d("Sum over the steps that recorded prompt tokens")]
    completion_tokens: Annotated[OptInt, _d("Sum over the steps that recorded completion tokens")]
    latency_s: Annotated[OptFloat, _d("Sum of the steps' latencies (those recorded)")]
    cost_usd: Annotated[OptFloat, _d("USD of the episode's tokens at the run's prices")]
    prefix_steps: Annotated[OptInt, _d("Continuation runs: steps repeated from the source run")]
    fixed: Annotated[OptBool, _d("Continuation runs: the planner's fix followed the prefix")]
    continued: Annotated[
        OptBool, _d("Continuation runs: the agent played on after the cut (false: a copy)")
    ]
    source_success: Annotated[OptBool, _d("Continuation runs: the source episode succeeded")]


class GoalRow(EpisodeKey, kw_only=True):
    """One goal of one replayed episode."""

    n_goals: Annotated[int, _d("Goals in the episode")]
    goal_index: Annotated[int, _d("0-based goal position")]
    goal_state: Annotated[str, _d("Goal state")]
    instruction: Annotated[OptStr, _d("Instruction shown while the goal was current")]
    c_opt: Annotated[int, _d("Static C_opt of the goal's segment")]
    c_opt_dyn: Annotated[OptInt, _d("C_opt from the situation when the goal became current")]
    reached: Annotated[bool, _d("The goal became current")]
    completed: Annotated[bool, _d("The goal was completed")]
    started_step: Annotated[OptInt, _d("Step at which the goal became current (0 for the first)")]
    completed_step: Annotated[OptInt, _d("Step that completed it")]
    steps_used: Annotated[int, _d("Scored steps taken while the goal was current")]
    switches: Annotated[int, _d("Successful switches taken while the goal was current")]
    perfect: Annotated[bool, _d("Completed in <= c_opt_dyn steps (PSR)")]


CLASSIFICATION_FIELDS = (
    "is_interaction",
    "hit_component",
    "hit_target",
    "hit_components",
    "nearest_target",
    "progress",
    "dist_before",
    "dist_after",
    "error_type",
    "error_detail",
    "error_group",
    "switch_class",
    "repetitive",
    "eer_valid",
    "distance",
    "weight",
)
"""The StepRow columns computed by `Classifier.classify`, in order (a contiguous block)."""

OUTPUT_RECORDS: dict[str, type] = {"step": StepRow, "episode": EpisodeRow, "goal": GoalRow}
