"""VGE Analytics: metrics, error taxonomy, comparisons and sweeps over replay output.

The package is in rooms (docs/ARCHITECTURE.md): `store` reads OUT safely, `metrics` holds
the registry and the metric files, `reports` what is built on them, `dashboard` the data
behind each page of the app, `synth` the synthetic benchmark, `live` and `play` the live
runs, `commands` the CLI. The names below are the public API of the first three.

Every function takes `out`, a replay output directory (PROTOCOL §7; the views are opened once per
directory and cached), and returns polars DataFrames with stable column names.

Metrics (PROTOCOL §6, one registry, SQL in `vge_analytics/sql/`):
    metrics(out, by=("run_id", "model"), metrics=None, where=None)
    episode_terms(out, metrics=None, where=None)   per-episode numerators/denominators
    polars_metrics(out, by=..., metrics=...)       the same numbers computed with polars
    metric_table(), registry(), get_metric(name), METRIC_NAMES, MAIN_TABLE
    CONTINUATION_METRICS (RecoveryRate, StepsToRecover: computed when named)

Metrics that users define (a folder of `.sql` files in the format of the built-ins):
    load_metrics(folder=None) -> MetricSet          default $VGE_METRICS_DIR, else built-ins
    metrics(out, ..., metrics_dir=DIR)              also episode_terms, compare, sweep
    rescore(out, DIR, against=None, by="run_id")    -> Rescore (values, ranks, Kendall tau-b)

Error taxonomy and navigation (PROTOCOL §5):
    error_distribution(out, by, where), error_groups(out, by, where),
    switch_classes(out, by, where)

Comparisons and budgets (the statistics: docs/STATISTICS.md):
    compare(out, run_a, run_b, seed=0, resamples=2000, cluster="device", correction="holm")
                                                     -> Comparison (clustered intervals, SEs,
                                                     design effects, corrected p-values)
    compare_all(out, runs=None, by="run_id", metric="SR") -> AllPairs (every pair, the
                                                     ranking and its tied groups)
    metric_intervals(out, metric="SR", by=("run_id",)) per group: the clustered interval
    power_of_pair(out, run_a, run_b, delta=5), plan(out, rate=0.5, delta=5, icc=None)
    repeated(out, runs=None, group_by=None) -> Repeated (pass@k, pass^k of seeds)
    sweep(out, lambdas=(2, 3, 4, 5), runs=None, metrics=("SR", "SSR"))

Trajectories side by side (`vge diff`):
    diff(out, run_a, run_b, episodes=None) -> Diff   per common episode: steps, success,
                                                     first error of each, first difference

Completeness (run.json's `complete`, PROTOCOL §7.5):
    completeness(out, run_ids=None), incomplete_runs(out, run_ids=None) -> [RunCompleteness]

Rows for a dashboard:
    runs(out), facets(out), episodes(out, where), goals(out, where), steps(out, where),
    episode_steps(out, run_id, episode_id), steps_with_error(out, error_type, where)

Live runs (`vge run`): `vge_analytics.live` (agents, the OpenAI-compatible client, the
prompt, the run writer; docs/LIVE.md). `vge_analytics.rendered_envs` registers the Gymnasium
environments with the rendered synthetic views:
`gymnasium.make("vge_analytics.rendered_envs:vge/RenderedDeviceRL-v0", bench=...)`.

Read-only SQL (within a memory and a time limit, see `store`):
    sql(out, "SELECT ...", timeout=300, memory_limit=None)   views steps, episodes, goals, runs
    with query_limits(memory="2GB", timeout=60): ...
                                         the analytics above within DuckDB's memory limit,
                                         60 s, and a cap on the process around each query
                                         (default: no time limit, no cap; the CLI's and the
                                         app's: 300 s, 512 MB and half of OUT's tables
                                         at most a quarter of the machine, capped:
                                         store.sized_memory_limit)
    with query_time_limit(60): ...       the time limit alone

`where` filters are `{column: value or list of values}` over columns of runs/episodes (and
of steps/goals where the result is computed from them); `by` lists grouping columns.
Errors are `replay.VGEError` subclasses with one-line messages.
"""

from typing import TYPE_CHECKING

from replay import lazy_names

from . import _errors
from ._errors import *  # noqa: F403 - every error class is public (_errors.__all__)

if TYPE_CHECKING:  # the names, imported when first used (`lazy_names`)
    from .metrics import (
        CONTINUATION_METRICS,
        MAIN_TABLE,
        METRIC_NAMES,
        METRICS_DIR_ENV,
        Metric,
        MetricSet,
        episode_terms,
        get_metric,
        load_metrics,
        metric_table,
        metrics,
        polars_metrics,
        registry,
    )
    from .reports import (
        ERROR_GROUPS,
        ERROR_LABELS,
        ERROR_TYPES,
        FORMATS,
        SWITCH_CLASSES,
        AllPairs,
        Comparison,
        Diff,
        Repeated,
        Rescore,
        RunCompleteness,
        compare,
        compare_all,
        competition_ranks,
        completeness,
        diff,
        error_distribution,
        error_groups,
        incomplete_runs,
        kendall_tau_b,
        mcnemar_exact,
        metric_intervals,
        parse_lambdas,
        plan,
        power_of_pair,
        render,
        render_latex,
        render_markdown,
        repeated,
        rescore,
        sweep,
        switch_classes,
    )
    from .store import (
        DEFAULT_BY,
        clear_cache,
        episode_steps,
        episodes,
        facets,
        goals,
        groupable_columns,
        open_store,
        query_limits,
        query_time_limit,
        runs,
        sql,
        steps,
        steps_with_error,
        table_columns,
    )

__all__ = [
    *_errors.__all__,
    "CONTINUATION_METRICS",
    "DEFAULT_BY",
    "ERROR_GROUPS",
    "ERROR_LABELS",
    "ERROR_TYPES",
    "FORMATS",
    "MAIN_TABLE",
    "METRIC_NAMES",
    "METRICS_DIR_ENV",
    "SWITCH_CLASSES",
    "AllPairs",
    "Comparison",
    "Metric",
    "MetricSet",
    "Rescore",
    "RunCompleteness",
    "clear_cache",
    "compare",
    "compare_all",
    "competition_ranks",
    "completeness",
    "Diff",
    "diff",
    "episode_steps",
    "episode_terms",
    "episodes",
    "error_distribution",
    "error_groups",
    "facets",
    "get_metric",
    "goals",
    "groupable_columns",
    "incomplete_runs",
    "kendall_tau_b",
    "load_metrics",
    "mcnemar_exact",
    "metric_intervals",
    "plan",
    "power_of_pair",
    "metric_table",
    "metrics",
    "open_store",
    "parse_lambdas",
    "polars_metrics",
    "query_limits",
    "query_time_limit",
    "registry",
    "render",
    "render_latex",
    "render_markdown",
    "repeated",
    "Repeated",
    "rescore",
    "runs",
    "sql",
    "steps",
    "steps_with_error",
    "sweep",
    "switch_classes",
    "table_columns",
]

__getattr__, __dir__ = lazy_names(__name__, __file__)
