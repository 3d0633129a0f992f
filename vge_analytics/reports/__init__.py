"""What is built on the metrics: paired comparisons, trajectories side by side, the error taxonomy and switch classes,
budget sweeps, rescoring and rankings, and tables rendered for people and for other tools."""

from typing import TYPE_CHECKING

from replay import lazy_names

if TYPE_CHECKING:  # the names, imported when first used (`lazy_names`)
    from ._compare import (
        Comparison,
        compare,
        mcnemar_exact,
    )
    from ._completeness import (
        INCOMPLETE_MARK,
        RunCompleteness,
        completeness,
        incomplete_runs,
        mark_incomplete,
        mark_rows,
        with_complete_column,
    )
    from ._defaults import (
        CLUSTER_UNITS,
        CORRECTIONS,
        DEFAULT_ALPHA,
        DEFAULT_CLUSTER,
        DEFAULT_CORRECTION,
        DEFAULT_DELTA,
        DEFAULT_POWER,
        DEFAULT_RESAMPLES,
        DEFAULT_RESCORE_BY,
        DEFAULT_SEED,
        DEFAULT_SWEEP_METRICS,
    )
    from ._diff import (
        DIFF_COLUMNS,
        NO_ERROR,
        Diff,
        diff,
    )
    from ._format import (
        ARROWS_LEGEND,
        FORMATS,
        MISSING,
        check_format,
        metrics_held,
        render,
        render_latex,
        render_markdown,
        render_sections,
        stream_chunks,
    )
    from ._ranking import (
        competition_ranks,
        kendall_tau_b,
    )
    from ._rescore import (
        Rescore,
        group_label,
        rescore,
    )
    from ._sweep import (
        parse_lambdas,
        sweep,
    )
    from ._taxonomy import (
        ERROR_GROUPS,
        ERROR_LABELS,
        ERROR_TYPES,
        SWITCH_CLASSES,
        error_distribution,
        error_groups,
        groups_of,
        switch_classes,
    )
    from .inference import (
        AllPairs,
        Repeated,
        adjust_p,
        compare_all,
        metric_intervals,
        plan,
        power_of_pair,
        repeated,
    )

__all__ = [
    "adjust_p",
    "ARROWS_LEGEND",
    "AllPairs",
    "check_format",
    "CLUSTER_UNITS",
    "compare_all",
    "CORRECTIONS",
    "DEFAULT_ALPHA",
    "DEFAULT_CLUSTER",
    "DEFAULT_CORRECTION",
    "DEFAULT_DELTA",
    "DEFAULT_POWER",
    "compare",
    "Comparison",
    "competition_ranks",
    "completeness",
    "DEFAULT_RESAMPLES",
    "DEFAULT_RESCORE_BY",
    "DEFAULT_SEED",
    "DEFAULT_SWEEP_METRICS",
    "Diff",
    "diff",
    "DIFF_COLUMNS",
    "error_distribution",
    "ERROR_GROUPS",
    "error_groups",
    "ERROR_LABELS",
    "ERROR_TYPES",
    "FORMATS",
    "group_label",
    "groups_of",
    "INCOMPLETE_MARK",
    "incomplete_runs",
    "kendall_tau_b",
    "mark_incomplete",
    "mark_rows",
    "mcnemar_exact",
    "metric_intervals",
    "metrics_held",
    "MISSING",
    "NO_ERROR",
    "parse_lambdas",
    "plan",
    "power_of_pair",
    "render",
    "Repeated",
    "repeated",
    "render_latex",
    "render_markdown",
    "render_sections",
    "Rescore",
    "rescore",
    "RunCompleteness",
    "stream_chunks",
    "sweep",
    "SWITCH_CLASSES",
    "switch_classes",
    "with_complete_column",
]

__getattr__, __dir__ = lazy_names(__name__, __file__)
