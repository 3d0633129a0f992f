"""The Significance page (AppTest) and the clustered intervals of the Leaderboard and of
Human vs VLM: what they show is the analytics API's."""

from __future__ import annotations

import pytest

import vge_analytics as va
from vge_analytics import dashboard as dash

from .test_pages import chart_data, charts, nums, open_page


def test_significance_page_without_repeated_runs(app_env):
    at = open_page("significance")
    expected = va.compare_all(app_env)
    ranking = at.dataframe[0].value
    assert list(ranking["run_id"]) == expected.ranking["run_id"].to_list()
    assert list(ranking["letters"]) == expected.ranking["letters"].to_list()
    assert dash.significance_caption(expected) in at.main.markdown[0].value
    (heat,) = charts(at)
    cells = chart_data(heat)[0]
    assert cells.height == 2 * expected.pairs.height
    assert "No model here was run with several seeds" in at.main.caption[-1].value


def test_significance_page_with_seeds(seeded_out, monkeypatch):
    monkeypatch.setenv("VGE_APP_OUT", str(seeded_out))
    at = open_page("significance")
    repeated = va.repeated(seeded_out)
    groups = at.dataframe[2].value
    assert list(groups["group"]) == ["sim-human", "sim-vlm-d", "sim-vlm-f"]
    assert list(groups["seeds"]) == [3, 2, 3]
    multi = repeated.groups.filter(repeated.groups["n_runs"] >= 2)
    assert nums(groups["SR mean"]) == pytest.approx(nums(multi["SR_mean"]))
    heat, curves = charts(at)
    lines = chart_data(curves)[0]
    assert sorted(set(lines["measure"])) == ["pass@k", "pass^k"]
    assert lines.height == 2 * (3 + 2 + 3)  # k = 1..n per group and measure
    at.selectbox(key="sig_by").set_value("model").run()
    assert not at.exception
    assert (
        list(at.dataframe[0].value["model"])
        == va.compare_all(seeded_out, by="model").ranking["model"].to_list()
    )


def test_leaderboard_and_human_vs_vlm_show_clustered_intervals(app_env):
    at = open_page()
    intervals = va.metric_intervals(app_env, by=["run_id", "model"])
    shown = next(d.value for d in at.dataframe if "CI low" in d.value.columns)
    assert nums(shown["CI low"]) == pytest.approx(nums(intervals["ci_low"]), nan_ok=True)
    assert nums(shown["design effect"]) == pytest.approx(nums(intervals["deff"]), nan_ok=True)
    assert any("resampling devices" in c.value for c in at.main.caption)

    at = open_page("human_vs_vlm")
    human, model = at.selectbox(key="hvv_human").value, at.selectbox(key="hvv_model").value
    cmp = va.compare(app_env, model, human)
    table = at.dataframe[0].value
    assert nums(table["SE"]) == pytest.approx(nums(cmp.metrics["se"]), nan_ok=True)
    assert dash.interval_caption(cmp) in [c.value for c in at.main.caption]
    at.selectbox(key="hvv_cluster").set_value("episode").run()
    naive = va.compare(app_env, model, human, cluster="episode")
    assert nums(at.dataframe[0].value["CI low"]) == pytest.approx(
        nums(naive.metrics["ci_low"]), nan_ok=True
    )
