"""The data behind each page of the dashboard (`app/`): typed, tested functions a page calls
directly, one module per page, with what several pages share (OUT and its version, pictures
of a step, an episode's MCAP file). The pages cache them with `st.cache_data`, keyed by OUT
and `out_version(OUT)`, the hash of its manifest, so a re-replay invalidates every result.
Everything reads the tables through the analytics' locked store (values bound, never
formatted into SQL).
"""

from typing import TYPE_CHECKING

from replay import lazy_names

if TYPE_CHECKING:  # the names, imported when first used (`lazy_names`)
    from ..store import bench_dir
    from ._budgets import (
        SWEEP_AUTO_LIMIT,
        SWEEP_SECONDS_PER_REPLAY,
        computed_sweep,
        stored_sweep,
        sweep_curves,
        sweep_size,
    )
    from ._episode_file import (
        episode_mcap,
    )
    from ._episode_viewer import (
        CLASSIFICATION_FIELDS,
        episode_labels,
        step_caption,
        step_classification,
        step_markdown,
        termination_label,
    )
    from ._error_page import (
        error_share_wide,
        error_step_sample,
    )
    from ._grounding import (
        CLICK_OUTCOMES,
        click_counts,
        click_points,
        clicked_targets,
        device_labels,
        interaction_views,
        scatter_boxes,
    )
    from ._human_vs_vlm import (
        comparison_rows,
        error_difference_rows,
        flip_rows,
        interval_caption,
        run_choices,
    )
    from ._leaderboard import (
        COST_COLUMNS,
        ORIGIN_MARKS,
        best_rows,
        cost_frontier,
        cost_table,
        group_labels,
        incomplete_groups,
        incomplete_note,
        interval_rows,
        metric_headers,
        metric_help,
        metrics_long,
        metrics_note,
        with_costs,
    )
    from ._navigation import (
        switch_summary,
    )
    from ._pictures import (
        CLICK_COLOR,
        NO_PICTURE,
        ROLE_COLORS,
        Box,
        ViewPicture,
        device_machine,
        draw_step,
        step_picture,
        view_boxes,
        view_picture,
    )
    from ._replay_output import (
        DEFAULT_OUT,
        OUT_ENV,
        OutSummary,
        check_out,
        column_values,
        out_summary,
        out_version,
        runs_matching,
    )
    from ._rescore_page import (
        rank_slopes,
        rescore_changes,
        rescore_rankings,
    )
    from ._side_by_side import (
        SIDE_STEP_COLUMNS,
        OptimalStep,
        SidePicture,
        default_episode,
        optimal_next_step,
        pair_labels,
        pair_rows,
        pair_summary,
        side_caption,
        side_picture,
        side_steps,
        step_label,
        step_marks,
    )
    from ._significance import (
        CLUSTER_WORDS,
        CORRECTION_WORDS,
        pair_matrix,
        passk_curves,
        ranking_order,
        repeated_rows,
        significance_caption,
    )
    from ._sql_page import (
        EXAMPLE_QUERIES,
        csv_bytes,
        sql_caption,
        sql_limits_note,
        sql_preview,
        table_columns_frame,
    )

__all__ = [
    "bench_dir",
    "best_rows",
    "Box",
    "check_out",
    "CLASSIFICATION_FIELDS",
    "CLICK_COLOR",
    "click_counts",
    "CLICK_OUTCOMES",
    "click_points",
    "CLUSTER_WORDS",
    "clicked_targets",
    "column_values",
    "comparison_rows",
    "computed_sweep",
    "CORRECTION_WORDS",
    "cost_frontier",
    "COST_COLUMNS",
    "cost_table",
    "csv_bytes",
    "default_episode",
    "DEFAULT_OUT",
    "device_labels",
    "device_machine",
    "draw_step",
    "episode_labels",
    "episode_mcap",
    "error_difference_rows",
    "error_share_wide",
    "error_step_sample",
    "EXAMPLE_QUERIES",
    "flip_rows",
    "group_labels",
    "incomplete_groups",
    "incomplete_note",
    "interaction_views",
    "interval_caption",
    "interval_rows",
    "metric_headers",
    "metric_help",
    "metrics_long",
    "metrics_note",
    "NO_PICTURE",
    "optimal_next_step",
    "OptimalStep",
    "ORIGIN_MARKS",
    "OUT_ENV",
    "out_summary",
    "out_version",
    "OutSummary",
    "pair_labels",
    "pair_matrix",
    "pair_rows",
    "pair_summary",
    "passk_curves",
    "rank_slopes",
    "ranking_order",
    "rescore_changes",
    "repeated_rows",
    "rescore_rankings",
    "ROLE_COLORS",
    "run_choices",
    "runs_matching",
    "scatter_boxes",
    "side_caption",
    "side_picture",
    "side_steps",
    "significance_caption",
    "SIDE_STEP_COLUMNS",
    "SidePicture",
    "sql_caption",
    "sql_limits_note",
    "sql_preview",
    "step_caption",
    "step_classification",
    "step_label",
    "step_markdown",
    "step_marks",
    "step_picture",
    "stored_sweep",
    "SWEEP_AUTO_LIMIT",
    "sweep_curves",
    "SWEEP_SECONDS_PER_REPLAY",
    "sweep_size",
    "switch_summary",
    "table_columns_frame",
    "termination_label",
    "view_boxes",
    "view_picture",
    "ViewPicture",
    "with_costs",
]

__getattr__, __dir__ = lazy_names(__name__, __file__)
