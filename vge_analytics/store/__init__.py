"""Reading OUT safely (PROTOCOL §9): a DuckDB connection that opens no file, over exactly the
Parquet files the manifest lists; the limits of user SQL, queries in a process of their own,
the read-only guard; filters and groupings; the tables as frames; the metric cache and the
results kept beside it."""

from typing import TYPE_CHECKING

from replay import lazy_names

if TYPE_CHECKING:  # the names, imported when first used (`lazy_names`)
    from ._benchmarks import Benchmark, benchmark_of, check_same_benchmark
    from ._bounds import (
        QueryBounds,
        query_bounds,
        query_limits,
        query_time_limit,
    )
    from ._cache import (
        cached_store,
    )
    from ._code import code_key
    from ._contents import local_contents
    from ._episode_terms import EPISODE_COLUMNS, kept_episode_terms
    from ._isolated import (
        IsolatedResult,
        query_isolated,
        run_isolated,
        warm_query_processes,
    )
    from ._kept import own_folder, prune_kept, read_kept
    from ._limits import (
        APP_MAX_ROWS,
        APP_TIMEOUT,
        CLI_MAX_ROWS,
        CLI_TIMEOUT,
        MAX_METRIC_FILE,
        SLOT_WAIT,
        SqlLimits,
        default_max_queries,
        format_size,
        process_memory_cap,
        text_too_large,
    )
    from ._locked import (
        locked_connection,
        register_all,
    )
    from ._page_result import CELL_CHARS, RESULT_BYTES, ResultCut, bound_result
    from ._ratios import (
        Ratio,
        ratio_query,
        term_name,
    )
    from ._results import MAX_RESULT_BYTES, MAX_RESULTS, kept_result
    from ._scope import (
        DEFAULT_BY,
        Filters,
        GroupBy,
        build_scope,
        check_columns,
        groupable_columns,
        grouped_aggregate,
        null_safe_join,
        order_by,
        parse_by,
        quote_ident,
        run_keys_scope,
    )
    from ._selection import (
        SelectionCheck,
        check_runs,
        check_selection,
        describe_filters,
    )
    from ._sizing import BASE_MEMORY, DATA_SHARE, sized_memory_limit, table_bytes
    from ._sql import (
        Batches,
        guarded_cursor,
        run_query,
        sql,
        sql_head,
        stream,
    )
    from ._standby import keep_standby, read_footers, standby_pid, stop_standbys
    from ._step_counts import COUNTS_TABLE, counted_steps
    from ._store import (
        NUMERIC_TYPES,
        Store,
        bench_dir,
        clear_cache,
        memory_store,
        open_store,
        resolve_input,
        run_entry,
        table_columns,
    )
    from ._tables import (
        episode_steps,
        episodes,
        facets,
        goals,
        run_columns,
        runs,
        steps,
        steps_with_error,
    )

__all__ = [
    "BASE_MEMORY",
    "bench_dir",
    "Benchmark",
    "benchmark_of",
    "check_same_benchmark",
    "DATA_SHARE",
    "run_entry",
    "warm_query_processes",
    "APP_MAX_ROWS",
    "APP_TIMEOUT",
    "default_max_queries",
    "describe_filters",
    "Batches",
    "cached_store",
    "build_scope",
    "check_columns",
    "check_runs",
    "check_selection",
    "clear_cache",
    "CLI_MAX_ROWS",
    "CLI_TIMEOUT",
    "COUNTS_TABLE",
    "DEFAULT_BY",
    "EPISODE_COLUMNS",
    "episode_steps",
    "episodes",
    "facets",
    "Filters",
    "format_size",
    "goals",
    "groupable_columns",
    "GroupBy",
    "grouped_aggregate",
    "guarded_cursor",
    "IsolatedResult",
    "CELL_CHARS",
    "RESULT_BYTES",
    "ResultCut",
    "bound_result",
    "local_contents",
    "locked_connection",
    "MAX_METRIC_FILE",
    "memory_store",
    "null_safe_join",
    "NUMERIC_TYPES",
    "open_store",
    "order_by",
    "own_folder",
    "prune_kept",
    "read_kept",
    "parse_by",
    "process_memory_cap",
    "QueryBounds",
    "query_bounds",
    "query_isolated",
    "query_limits",
    "query_time_limit",
    "quote_ident",
    "Ratio",
    "ratio_query",
    "kept_result",
    "keep_standby",
    "read_footers",
    "standby_pid",
    "stop_standbys",
    "code_key",
    "counted_steps",
    "kept_episode_terms",
    "MAX_RESULT_BYTES",
    "MAX_RESULTS",
    "register_all",
    "resolve_input",
    "run_isolated",
    "run_keys_scope",
    "run_query",
    "SelectionCheck",
    "run_columns",
    "runs",
    "SLOT_WAIT",
    "sql",
    "sql_head",
    "sized_memory_limit",
    "SqlLimits",
    "steps",
    "steps_with_error",
    "Store",
    "stream",
    "table_bytes",
    "table_columns",
    "term_name",
    "text_too_large",
]

__getattr__, __dir__ = lazy_names(__name__, __file__)
