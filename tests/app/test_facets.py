"""Which run fields the dashboard offers as facets (`dash.offered_facets`): the categories of
how runs were set up, never what a run did (run.json's totals), an address or free text, nor
a field with one value or with more values than a person scans."""

from __future__ import annotations

from pathlib import Path

import vge_analytics as va
from vge_analytics import dashboard as dash
from vge_analytics.reports.inference import RUN_TOTALS

from .test_leaderboard_costs import kettle_bench, priced_out  # noqa: F401


def test_only_low_cardinality_categories_are_offered() -> None:
    fields = {
        "meta_temperature": [0.0, 0.7],
        "meta_history": [1, 3, None],  # no value counts as one
        "meta_provider": ["openai", "vllm"],
        "meta_cost_usd": [0.01, 0.02],
        "meta_prompt_tokens": [100, 200],
        "meta_latency_seconds": [1.5, 2.5],
        "meta_complete": [False, True],
        "meta_base_url": ["http://127.0.0.1:8000/v1", "https://api.openai.com/v1"],
        "meta_seed": [0],  # one value: nothing to choose
        "meta_note": ["short", "a note " * 10],  # longer than MAX_FACET_TEXT: free text
        "meta_prompt": ["one line", "two\nlines"],
        "meta_run_label": [f"r{i}" for i in range(dash.MAX_FACET_VALUES + 1)],
        "meta_shard": [f"s{i}" for i in range(dash.MAX_FACET_VALUES)],  # at the bound: kept
    }
    assert dash.offered_facets(fields) == {
        "meta_temperature": [0.0, 0.7],
        "meta_history": [1, 3, None],
        "meta_provider": ["openai", "vllm"],
        "meta_shard": [f"s{i}" for i in range(dash.MAX_FACET_VALUES)],
    }
    # Every total of run.json is refused by its name, whatever its values.
    totals = {f"meta_{key}": ["a", "b"] for key in RUN_TOTALS}
    assert dash.offered_facets(totals) == {}
    assert dash.offered_facets({}) == {}


def test_the_facets_of_a_replayed_output(priced_out: Path) -> None:  # noqa: F811
    # Four runs of the kettle benchmark; three priced (`prompt_price_per_mtok` 1.0, c none),
    # d written as cut short (`complete: false`, 2 infrastructure failures: totals).
    assert va.facets(priced_out) == {
        "meta_complete": [False, None],
        "meta_infrastructure_failures": [2, None],
        "meta_prompt_price_per_mtok": [1.0, None],
    }
    assert dash.run_facets(priced_out) == {"meta_prompt_price_per_mtok": [1.0, None]}
