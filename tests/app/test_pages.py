"""One AppTest per page: it runs without exception, shows its widgets, and the numbers it shows
are the analytics API's (on the replayed tiny synthetic benchmark)."""

from __future__ import annotations

import json

import polars as pl
import pyarrow as pa
import pytest
from streamlit.testing.v1 import AppTest

import vge_analytics as va
from vge_analytics import ERROR_LABELS, compare, error_distribution, play, sweep, switch_classes
from vge_analytics import dashboard as dash

from ..vge_analytics.metrics.metric_files import RUNAWAY, metric_text, write_folder
from ..vge_analytics.store.kept import copy_out, kept_files
from .conftest import APP


def open_page(page: str | None = None, query: dict | None = None, state: dict | None = None):
    """Run the app (the entry file routes) on `views/<page>.py`; fails on any exception."""
    at = AppTest.from_file(str(APP), default_timeout=60)
    for key, value in (state or {}).items():
        at.session_state[key] = value
    at.run()
    if page is not None:
        at.switch_page(f"views/{page}.py")
        for key, value in (query or {}).items():
            at.query_params[key] = value
        at.run()
    assert not at.exception, [e.message for e in at.exception]
    return at


def rerun(at: AppTest) -> AppTest:
    at.run()
    assert not at.exception, [e.message for e in at.exception]
    return at


def charts(at: AppTest) -> list:
    return list(at.get("vega_lite_chart"))


def chart_data(chart) -> list[pl.DataFrame]:
    """The datasets a Vega-Lite chart element carries (Arrow IPC)."""
    frames = []
    for ds in chart.proto.datasets:
        frames.append(pl.from_arrow(pa.ipc.open_stream(ds.data.data).read_all()))
    return frames


def nums(values) -> list[float]:
    """Numbers with null as NaN (tables shown hold NaN where the API has null)."""
    return [float("nan") if v is None else float(v) for v in list(values)]


def by_group(df, column: str) -> dict:
    return dict(zip(df["group"], df[column], strict=True))


# -------------------------------------------------------------------------- sidebar


def test_sidebar_shows_out_and_facets(app_env):
    at = open_page()
    assert str(app_env) in at.sidebar.caption[0].value
    assert "216 episodes" in at.sidebar.caption[1].value
    labels = [m.label for m in at.sidebar.multiselect]
    assert "history_length" in labels
    assert "synth_scale" not in labels  # a facet with one value filters nothing


def test_missing_out_is_explained(monkeypatch, tmp_path):
    monkeypatch.setenv("VGE_APP_OUT", str(tmp_path / "logs-replayed"))
    at = AppTest.from_file(str(APP), default_timeout=60).run()
    assert not at.exception
    assert any("run `vge demo`" in e.value for e in at.error)
    assert not at.dataframe


# ----------------------------------------------------------------------- leaderboard


def test_leaderboard_shows_each_runs_metrics(app_env):
    at = open_page()
    assert at.title[0].value == "Leaderboard"
    shown = at.dataframe[0].value
    expected = va.metrics(app_env)
    assert list(shown["group"]) == expected["run_id"].to_list()
    for name in ("SR", "SSR", "EIR", "VSPS", "AvgWDist"):
        assert nums(shown[name]) == pytest.approx(nums(expected[name]), nan_ok=True)
    bars = chart_data(charts(at)[0])[0]
    sr = bars.filter(pl.col("metric") == "SR")
    assert by_group(sr, "value") == pytest.approx(dict(expected.select("run_id", "SR").iter_rows()))


@pytest.mark.parametrize(
    ("page", "drawn", "bars"),
    [(None, 1, None), ("errors", 2, None), ("navigation", 3, None), ("grounding", 2, 18)],
)
def test_charts_of_many_groups_are_drawn_when_asked(app_env, monkeypatch, page, drawn, bars):
    monkeypatch.setattr(dash, "CHART_AUTO_GROUPS", 8)  # 9 runs: one too many
    at = open_page(page)
    (toggle,) = at.toggle
    assert toggle.label.startswith("Draw the charts: 9 groups, ")
    if bars is not None:
        assert f" {bars} bars " in toggle.label
    assert not toggle.value
    shown = len(charts(at))  # (the grounding scatter and no cost chart: no group chart)
    toggle.set_value(True)
    rerun(at)
    assert len(charts(at)) == shown + drawn
    if page is None:
        bars = chart_data(charts(at)[0])[0]
        sr = bars.filter(pl.col("metric") == "SR")
        expected = dict(va.metrics(app_env).select("run_id", "SR").iter_rows())
        assert by_group(sr, "value") == pytest.approx(expected)


def test_leaderboard_filters_and_groups(app_env):
    at = open_page()
    at.multiselect[1].select("Lamp")  # category
    at.selectbox(key="leaderboard_by").select("model")
    rerun(at)
    shown = at.dataframe[0].value
    expected = va.metrics(app_env, by="model", where={"category": ["Lamp"]})
    assert list(shown["group"]) == expected["model"].to_list()
    assert nums(shown["SR"]) == pytest.approx(nums(expected["SR"]), nan_ok=True)


def test_facet_filter_applies_to_every_page(app_env):
    at = open_page()
    at.sidebar.multiselect[0].select("3")  # history_length
    rerun(at)
    assert list(at.dataframe[0].value["group"]) == ["sim-vlm-f-hist3"]
    at.switch_page("views/navigation.py")
    rerun(at)
    assert list(at.dataframe[0].value["group"]) == ["sim-vlm-f-hist3"]


# --------------------------------------------------------------------------- errors


def test_errors_page_shares_and_drill_down(app_env):
    at = open_page("errors")
    assert at.title[0].value == "Errors"
    assert [t.label for t in at.tabs] == ["Compare groups", "Pie of one group", "Table"]
    table = at.dataframe[0].value
    dist = error_distribution(app_env, labels=True)
    human = dist.filter(pl.col("run_id") == "sim-human")
    row = table[table["group"] == "sim-human"].iloc[0]
    for label, share in human.select("label", "share").iter_rows():
        assert row[label] == pytest.approx(share)
    assert len(charts(at)) == 3  # stacked types, stacked groups, the pie

    at.selectbox(key="errors_drill_type").select("params_error")
    at.multiselect(key="errors_drill_runs").select("sim-vlm-f")
    rerun(at)
    steps = va.steps_with_error(app_env, "params_error", where={"run_id": ["sim-vlm-f"]})
    label = ERROR_LABELS["params_error"]
    assert f"{steps.height} steps with {label}" in at.main.caption[-1].value
    assert at.dataframe[1].value["step"].tolist() == steps["step"].to_list()[: ui_max_rows()]
    assert len(at.dataframe[1].value) == min(steps.height, ui_max_rows())


def ui_max_rows() -> int:
    from app import _tables

    return _tables.MAX_ROWS


def test_drill_down_link_opens_the_episode(app_env):
    from app import _links, _tables

    class Selection:
        class selection:  # noqa: N801 - the shape of Streamlit's dataframe selection
            rows = [0]

    steps = va.steps_with_error(app_env, "invalid_coord", columns=list(_tables.STEP_COLUMNS))
    row = _tables.selected_row(steps, Selection())
    assert row == steps.row(0, named=True)
    assert _links.viewer_query(row["run_id"], row["episode_id"], row["step"]) == {
        "run": row["run_id"],
        "episode": row["episode_id"],
        "step": str(row["step"]),
    }
    assert _tables.selected_row(steps, object()) is None


# ----------------------------------------------------------------------- navigation


def test_navigation_page_switch_classes(app_env):
    at = open_page("navigation")
    assert at.title[0].value == "Navigation"
    table = at.dataframe[0].value
    classes = switch_classes(app_env).filter(pl.col("run_id") == "sim-vlm-f")
    ratios = va.metrics(app_env, metrics=["VSPS", "GVPE"], where={"run_id": ["sim-vlm-f"]})
    row = table[table["group"] == "sim-vlm-f"].iloc[0]
    for cls, share in classes.select("switch_class", "share").iter_rows():
        assert row[f"{cls} %"] == pytest.approx(share)
    assert row["VSPS"] == pytest.approx(ratios["VSPS"][0])
    assert row["GVPE"] == pytest.approx(ratios["GVPE"][0])
    assert len(charts(at)) == 3


# ------------------------------------------------------------------------ grounding


def test_grounding_page_distances_and_scatter(app_env):
    at = open_page("grounding")
    table = at.dataframe[0].value
    expected = va.metrics(app_env, metrics=["AvgDist", "AvgWDist"])
    assert nums(table["AvgDist"]) == pytest.approx(nums(expected["AvgDist"]), nan_ok=True)
    first = dash.interaction_views(app_env).row(0, named=True)
    assert at.selectbox(key="grounding_device").value == first["device_id"]
    scatter = charts(at)[-1]
    data = chart_data(scatter)
    points = dash.click_points(app_env, first["device_id"], first["view"])
    assert any(d.height == points.height and "outcome" in d.columns for d in data)
    assert f"{points.height} clicks" in at.main.caption[-1].value


# -------------------------------------------------------------------------- budgets


def test_budgets_page_sweep(app_env):
    runs = va.runs(app_env)["run_id"].to_list()
    at = open_page("budgets")
    assert at.title[0].value == "Budgets"
    table = at.dataframe[0].value
    expected = sweep(app_env, [2, 3, 4, 5])
    assert nums(table["SR"]) == pytest.approx(nums(expected["SR"]), nan_ok=True)
    lines = chart_data(charts(at)[0])[0]
    assert lines.height == expected.height
    assert lines.filter(pl.col("lambda") == 2)["gain"].to_list() == [0.0] * 9
    stored = dash.stored_sweep(app_env, runs, [2, 3, 4, 5])  # kept for the next visit
    assert stored is not None and stored.equals(expected)


def test_budgets_page_asks_before_a_large_sweep(app_env, monkeypatch):
    monkeypatch.setattr(dash, "SWEEP_AUTO_LIMIT", 10)
    at = open_page("budgets")
    at.multiselect(key="budgets_lambdas").set_value([2.5, 3])
    rerun(at)
    size = dash.sweep_size(app_env, va.runs(app_env)["run_id"].to_list(), [2.5, 3])
    assert at.button[0].label.startswith(f"Compute the sweep: {size:,} episode replays")
    assert not charts(at)
    at.button[0].click()
    rerun(at)
    assert len(charts(at)) == 1


# --------------------------------------------------------------------- human vs VLM


def test_human_vs_vlm_page(app_env):
    at = open_page("human_vs_vlm")
    human, model = at.selectbox(key="hvv_human").value, at.selectbox(key="hvv_model").value
    assert human == "sim-human"
    cmp = compare(app_env, model, human)
    table = at.dataframe[0].value
    assert nums(table[human]) == pytest.approx(nums(cmp.metrics["B"]), nan_ok=True)
    assert nums(table["CI low"]) == pytest.approx(nums(cmp.metrics["ci_low"]), nan_ok=True)
    assert f"{cmp.n_common} common episodes" in at.main.markdown[0].value
    errors = at.dataframe[1].value
    assert nums(errors["difference (pp)"]) == pytest.approx(
        nums(cmp.errors["diff_pp"]), nan_ok=True
    )
    assert f"{cmp.flips.height} episodes solved by one run only" in at.main.caption[-1].value
    assert len(charts(at)) == 2


# --------------------------------------------------------------------- side by side


def test_side_by_side_page(app_env):
    at = open_page("side_by_side")
    run_a, run_b = at.selectbox(key="sbs_a").value, at.selectbox(key="sbs_b").value
    assert run_a == "sim-human" and run_b != run_a  # the reference first, as on Human vs VLM
    rows = dash.pair_rows(app_env, run_a, run_b)
    episode = at.selectbox(key="sbs_episode").value
    assert episode == dash.default_episode(rows)
    row = rows.filter(pl.col("episode_id") == episode).row(0, named=True)
    assert at.main.markdown[0].value == dash.pair_summary(row)
    assert at.select_slider(key="sbs_step").value == 0
    assert len(at.get("image")) == 2  # one picture per run
    assert dict(at.query_params) == {"a": run_a, "b": run_b, "episode": episode, "step": "0"}


def test_side_by_side_from_a_link_with_marks(app_env):
    rows = dash.pair_rows(app_env, "sim-vlm-a", "sim-vlm-f")
    marked = rows.filter(
        pl.col("first_difference") > 0,
        pl.col("first_error_b").is_not_null(),
        pl.col("steps_a") != pl.col("steps_b"),
    )
    row = marked.row(0, named=True)
    query = {"a": "sim-vlm-a", "b": "sim-vlm-f", "episode": row["episode_id"], "step": "1"}
    at = open_page("side_by_side", query=query)
    assert at.selectbox(key="sbs_b").value == "sim-vlm-f"
    assert at.selectbox(key="sbs_episode").value == row["episode_id"]
    slider = at.select_slider(key="sbs_step")
    assert slider.value == 1
    marks = dash.step_marks(row)
    logged = [
        va.episode_steps(app_env, r, row["episode_id"]).height for r in ("sim-vlm-a", "sim-vlm-f")
    ]
    steps = max(logged)  # every logged step, truncated ones included, as in the viewer
    assert slider.options == [dash.step_label(k, marks) for k in range(steps)]
    jumps = {b.label: b for b in at.button}
    first_difference = f"Step {row['first_difference']}: first difference"
    assert any(label.startswith(first_difference) for label in jumps)
    next(b for label, b in jumps.items() if label.startswith(first_difference)).click()
    rerun(at)
    assert at.select_slider(key="sbs_step").value == row["first_difference"]
    assert at.query_params["step"] == str(row["first_difference"])
    # Past the end of the shorter log, its side says so.
    at.select_slider(key="sbs_step").set_value(steps - 1)
    rerun(at)
    short = "AB"[logged.index(min(logged))]
    ended = f"{short}'s log ended at step {min(logged) - 1}: no step {steps - 1} to show"
    assert any(i.value.startswith(ended) for i in at.info)
    headings = [m.value for m in at.markdown if m.value.startswith(f"**{short} · ")]
    assert headings[-1].endswith(f"its log ended at step {min(logged) - 1}")  # not "of 1"
    assert len(at.get("image")) == 1


# ------------------------------------------------------------------- episode viewer


def test_episode_viewer_from_a_link(app_env):
    episodes = va.episodes(app_env, where={"run_id": "sim-vlm-f"})
    episode = episodes.filter(pl.col("L_act") > 2)["episode_id"][0]
    at = open_page("episode_viewer", query={"run": "sim-vlm-f", "episode": episode, "step": "2"})
    assert at.selectbox(key="viewer_run").value == "sim-vlm-f"
    assert at.selectbox(key="viewer_episode").value == episode
    assert at.slider(key="viewer_step").value == 2
    steps = va.episode_steps(app_env, "sim-vlm-f", episode)
    text = at.main.markdown[0].value
    assert "**Step 2**" in text and steps["action_raw"][2] in text
    assert at.get("image")  # the step picture
    assert at.get("download_button")[0].proto.label.startswith("Download episode as MCAP")

    at.slider(key="viewer_step").set_value(1)
    rerun(at)
    assert "**Step 1**" in at.main.markdown[0].value
    assert at.query_params["step"] == "1"


def test_episode_viewer_default(app_env):
    at = open_page("episode_viewer")
    assert at.selectbox(key="viewer_run").value == va.runs(app_env)["run_id"][0]
    assert "**Step 0**" in at.main.markdown[0].value
    classification = at.dataframe[0].value
    assert list(classification["field"]) == list(dash.CLASSIFICATION_FIELDS)


# ------------------------------------------------------------------------------ SQL


def test_sql_page_runs_queries_and_refuses_writes(app_env):
    at = open_page("sql")
    first = next(iter(dash.EXAMPLE_QUERIES.values()))
    assert at.text_area(key="sql_query").value == first
    shown = at.dataframe[1].value
    assert len(shown) == va.runs(app_env)["model"].n_unique()

    at.text_area(key="sql_query").input("DROP TABLE steps")
    rerun(at)
    assert at.error and not at.exception

    name = "Dangerous actions per run"
    at.selectbox(key="sql_example").select(name)
    rerun(at)
    assert at.text_area(key="sql_query").value == dash.EXAMPLE_QUERIES[name]
    assert len(at.dataframe[1].value) == 9


def test_sql_page_keeps_an_examples_result_not_a_users_query(tiny_out, tmp_path, monkeypatch):
    from vge_analytics.store import IsolatedResult
    from vge_analytics.store._results import _read

    out = copy_out(tiny_out, tmp_path / "out")
    monkeypatch.setenv("VGE_APP_OUT", str(out))

    def kept_queries() -> list[IsolatedResult]:
        values = [_read(path) for path in kept_files(out, "result-*.arrow")]
        return [value for found, value in values if found and isinstance(value, IsolatedResult)]

    at = open_page("sql")  # the first example, as the page opens
    (kept,) = kept_queries()
    shown = at.dataframe[1].value
    assert kept.frame.columns == list(shown.columns)
    assert kept.frame.to_pandas().equals(shown.reset_index(drop=True))

    at.text_area(key="sql_query").input("SELECT 42 AS answer")
    rerun(at)
    assert list(at.dataframe[1].value["answer"]) == [42]
    assert [k.frame.columns for k in kept_queries()] == [kept.frame.columns]  # not kept


# ------------------------------------------------------------------- metrics folder


def column_labels(element) -> dict[str, str]:
    """{column: header label} of a dataframe element's column configuration."""
    import json

    config = json.loads(element.proto.columns)
    return {c: v["label"] for c, v in config.items() if "label" in v}


def test_leaderboard_shows_the_folders_metrics(app_env, metrics_env):
    at = open_page()
    shown = at.dataframe[0].value
    expected = va.metrics(app_env, metrics_dir=metrics_env)
    assert list(shown.columns[-2:]) == ["AvgWDist", "SR-multi"]
    for name in ("SR", "SSR", "SR-multi"):
        assert nums(shown[name]) == pytest.approx(nums(expected[name]), nan_ok=True)
    assert nums(shown["SR"]) == pytest.approx(nums(expected["SSR"]), nan_ok=True)  # override
    labels = column_labels(at.dataframe[0])
    assert (labels["SR"], labels["SSR"], labels["SR-multi"]) == ("SR ↑ ✎", "SSR ↑", "SR-multi ↑ +")
    assert any("✎ overridden: SR; + added: SR-multi" in c.value for c in at.main.caption)
    title = f"The paper's metrics, SR overridden and SR-multi added by {metrics_env}. One row"
    assert at.main.caption[0].value.startswith(title)
    assert f"built-in + `{metrics_env}`" in at.sidebar.caption[-1].value


def test_rescore_page(app_env, metrics_env):
    at = open_page("rescore")
    assert at.title[0].value == "Rescore"
    result = va.rescore(app_env, metrics_env, by=("run_id", "model"))
    rankings = at.dataframe[0].value
    assert list(rankings["metric"]) == ["SR", "SR-multi"]
    assert rankings["Kendall τ-b"][0] == pytest.approx(result.summary["kendall_tau_b"][0])
    changes = at.dataframe[1].value
    sr = result.rows.filter(pl.col("metric") == "SR")
    assert list(changes["group"]) == sr["run_id"].to_list()
    assert nums(changes["after"]) == pytest.approx(nums(sr["after"]))
    assert list(changes["rank after"]) == sr["rank_after"].to_list()
    assert len(charts(at)) == 1  # ranks before -> after
    slope = chart_data(charts(at)[0])[0]
    assert slope.height == 2 * sr.height

    at.selectbox(key="rescore_metric").select("SR-multi")
    at.selectbox(key="rescore_by").select("model")
    rerun(at)
    by_model = va.rescore(app_env, metrics_env, by=("model",))
    multi = by_model.rows.filter(pl.col("metric") == "SR-multi")
    changes = at.dataframe[1].value
    assert list(changes["group"]) == multi["model"].to_list()
    assert list(changes["move"]) == ["new"] * multi.height


def test_rescore_page_without_a_folder(app_env, monkeypatch):
    monkeypatch.delenv("VGE_METRICS_DIR", raising=False)
    at = open_page("rescore")
    assert "--metrics-dir DIR" in at.info[0].value
    assert not at.dataframe


def test_a_bad_metrics_folder_is_explained(app_env, tmp_path, monkeypatch):
    (tmp_path / "x.sql").write_text("-- metric: X\n")
    monkeypatch.setenv("VGE_METRICS_DIR", str(tmp_path))
    at = AppTest.from_file(str(APP), default_timeout=60).run()
    assert not at.exception
    assert at.sidebar.error[0].value == "Unusable metrics folder"
    assert f"{tmp_path}/x.sql:1: missing header keys" in at.main.error[0].value
    assert not at.dataframe


# ----------------------------------------------------------------------------- play


def open_play(bench, run, monkeypatch) -> AppTest:
    """The app as `vge play BENCH --out RUN` runs it (`-- --bench BENCH --run RUN`)."""
    monkeypatch.setattr("sys.argv", ["streamlit_app.py", "--bench", str(bench), "--run", str(run)])
    at = AppTest.from_file(str(APP), default_timeout=60)
    return rerun(at)


def play_click(at: AppTest, x: int, y: int, when: int) -> AppTest:
    """What the image component reports after a click (displayed 600 px wide)."""
    key = f"play_click:{at.session_state['play_episode']}"
    at.session_state[key] = {"x": x, "y": y, "width": 600, "height": 600, "unix_time": when}
    return rerun(at)


def test_play_page_writes_each_step_of_a_human_run(tiny_out, tmp_path, monkeypatch):
    bench, run = tiny_out.parent / "synth" / "bench", tmp_path / "bob"
    at = open_play(bench, run, monkeypatch)
    assert at.title[0].value == "Play"
    assert not at.sidebar.multiselect  # no run facets: there is no replay output here
    episode = at.selectbox(key="play_episode").value
    assert episode == "ElectricKettle_000-00"  # the next one not played: the first
    assert at.info[0].value == "Goal 1 of 1: Disconnect the kettle from the mains"
    assert [(m.label, m.value) for m in at.metric] == [
        ("Steps taken", "0"), ("Steps left", "10"), ("Left for this goal", "10"),
    ]  # fmt: skip
    assert at.radio(key="play_action").options == list(play.CLICK_ACTIONS)
    assert at.text_input(key="play_params:Press").value == "0"

    # A click at pixel (300, 150) of the view shown 600 wide: (500, 250). The initial view is
    # axonometric, so the press is refused (invalid_action), and still a step.
    at = play_click(at, 300, 150, when=1)
    assert at.error[0].value.startswith("Step 0: `Press(coord=[500, 250], params=[0])`")
    at = rerun(at)  # the same click reported again is not a second step
    at.selectbox(key="play_view").select("front")
    button(at, "Switch view").click()  # without a point
    at = rerun(at)
    assert at.success[0].value.startswith("Step 1: `Switch_view(params=[front])`")
    at.radio(key="play_action").set_value("Rotate")
    at = rerun(at)
    at.text_input(key="play_params:Rotate").input("1, 2")
    at = play_click(at, 60, 540, when=2)  # (100, 900)
    journal = lines_of(next((run / "playing").glob("*.jsonl")))
    assert journal[0] == {"episode_id": episode}
    assert [s["action"] for s in journal[1:]] == [
        {"type": "Press", "coord": [500, 250], "params": ["0"]},
        {"type": "Switch_view", "coord": None, "params": ["front"]},
        {"type": "Rotate", "coord": [100, 900], "params": ["1", "2"]},
    ]
    assert [m.value for m in at.metric][:2] == ["3", "7"]
    assert "Unfinished: 3 steps played so far." in [c.value for c in at.caption]
    assert at.dataframe[0].value["step"].to_list() == [2, 1, 0]  # newest first

    button(at, "Give up").click()
    at = rerun(at)
    assert at.success[0].value.startswith("**Ended by the player.** 0 of 1 goal completed in 3")
    assert not list((run / "playing").glob("*.jsonl"))
    (line,) = lines_of(run / "episodes.jsonl")
    assert [s["action"] for s in line["steps"]] == [s["action"] for s in journal[1:]]
    button(at, "Next episode").click()
    at = rerun(at)
    assert at.selectbox(key="play_episode").value == "ElectricKettle_000-01"
    assert "1 of 24 episodes played" in " ".join(c.value for c in at.sidebar.caption)


def test_play_page_resumes_or_discards_an_unfinished_episode(tiny_out, tmp_path, monkeypatch):
    bench, run = tiny_out.parent / "synth" / "bench", tmp_path / "carol"
    at = open_play(bench, run, monkeypatch)
    at = play_click(at, 300, 300, when=1)
    at = play_click(at, 30, 30, when=2)
    # The page is closed; a new session opens it again.
    at = open_play(bench, run, monkeypatch)
    assert at.info[0].value.startswith("2 steps of this episode were played before")
    button(at, "Resume").click()
    at = rerun(at)
    assert [m.value for m in at.metric][0] == "2"
    assert at.dataframe[0].value["action"].to_list() == [
        "Press(coord=[50, 50], params=[0])",
        "Press(coord=[500, 500], params=[0])",
    ]
    at = open_play(bench, run, monkeypatch)
    button(at, "Discard and start over").click()
    at = rerun(at)
    assert at.info[0].value.startswith("The unfinished steps were moved to ")
    assert [m.value for m in at.metric][0] == "0"  # a new start
    assert len(list((run / "playing" / "discarded").glob("*.jsonl"))) == 1


def test_play_page_says_what_is_wrong(tmp_path, monkeypatch):
    at = open_play(tmp_path / "no-bench", tmp_path / "run", monkeypatch)
    assert at.error[0].value.startswith(f"{tmp_path / 'no-bench'}: benchmark directory not found")


def button(at: AppTest, label: str):
    return next(b for b in at.button if b.label == label)


def lines_of(path) -> list[dict]:
    return [json.loads(line) for line in path.read_text().splitlines() if line.strip()]


def _errors_with_metrics(monkeypatch, folder, options: list[str], timeout: float) -> list[str]:
    """The errors the first page shows with the metric files of `folder`, the app started
    with `options` as `vge app` passes them on (no exception escapes)."""
    monkeypatch.setenv("VGE_METRICS_DIR", str(folder))
    monkeypatch.setattr("sys.argv", ["streamlit_app.py", *options])
    at = AppTest.from_file(str(APP), default_timeout=timeout).run()
    assert not at.exception, [e.message for e in at.exception]
    return [e.value for e in at.main.error]


def test_a_runaway_metric_ends_with_one_line_on_the_page(app_env, tmp_path, monkeypatch):
    folder = write_folder(tmp_path / "runaway", {"runaway.sql": RUNAWAY})
    # As `vge app --query-timeout 0.5` starts the app.
    assert _errors_with_metrics(monkeypatch, folder, ["--query-timeout", "0.5"], 60) == [
        f"{folder / 'runaway.sql'}: the query of this metric file ran past its time limit of "
        "0.5 s and was stopped"
    ]


def test_a_metric_past_its_memory_bound_ends_with_one_line_on_the_page(
    app_env, tmp_path, monkeypatch
):
    # Each value is 400 MB that DuckDB's memory limit does not count: the query runs in a
    # query process of its own, capped (tests/hostile/test_metric_bounds.py measures it).
    numerator = "sum(length(repeat(episode_id, 20000000)))"
    folder = write_folder(
        tmp_path / "repeat", {"repeat.sql": metric_text("Repeat", numerator, "count(*)")}
    )
    assert _errors_with_metrics(monkeypatch, folder, ["--sql-memory-limit", "256MB"], 120) == [
        f"{folder / 'repeat.sql'}: the query of this metric file needed more memory than its "
        "limit (256 MB in memory, 512 MB on disk) and was stopped"
    ]
