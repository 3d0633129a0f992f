"""The dashboard's functions (`vge_analytics.dashboard`), against the analytics API they
reshape and the replayed tiny synthetic benchmark."""

from __future__ import annotations

import copy
import hashlib
import io
import os
import re
import shutil
import subprocess
import time
from pathlib import Path

import polars as pl
import pytest
from PIL import Image

import replay
import vge_analytics as va
from vge_analytics import OutputDirError, compare, error_distribution, sql, switch_classes
from vge_analytics import dashboard as dash
from vge_analytics.dashboard._budgets import _sweep_cache_file
from vge_analytics.play import result_headline
from vge_analytics.reports import MISSING
from vge_analytics.store import resolve_input
from vge_analytics.store._limits import SqlLimits

from ..vge_analytics.conftest import (
    KETTLE_CASES,
    KETTLE_RUN,
    OVEN_CASES,
    OVEN_RUN,
    _case,
    replay_to,
    write_bench,
    write_run,
)
from ..vge_analytics.metrics.metric_files import SR_MULTI, write_folder

# ------------------------------------------------------------------------------ OUT


def test_check_out_says_what_to_run(tmp_path):
    with pytest.raises(
        OutputDirError, match=r"No replay output at .*logs-replayed: run `vge demo`"
    ):
        dash.check_out(tmp_path / "logs-replayed")
    with pytest.raises(OutputDirError, match=r"run `vge demo`, or `vge replay RUN\.\.\."):
        dash.check_out(tmp_path / "elsewhere")
    (tmp_path / "half" / "steps").mkdir(parents=True)
    with pytest.raises(OutputDirError, match=r"not a replay output directory \(no episodes/"):
        dash.check_out(tmp_path / "half")


def test_check_out_accepts_a_replay_output(tiny_out):
    assert dash.check_out(tiny_out) == tiny_out.resolve()


def test_out_version_follows_the_manifest(tiny_out, tmp_path):
    copy = tmp_path / "out"
    shutil.copytree(tiny_out, copy)
    before = dash.out_version(copy)
    assert before == dash.out_version(tiny_out)
    manifest = copy / "manifest.json"
    manifest.write_text(manifest.read_text().replace('"runs"', '"runs" ', 1))
    assert dash.out_version(copy) != before


def _read_counter(monkeypatch) -> list[Path]:
    """The paths `Path.read_bytes` reads from now on (the manifest's hashing counted)."""
    reads: list[Path] = []
    original = Path.read_bytes

    def counted(self: Path) -> bytes:
        reads.append(self)
        return original(self)

    monkeypatch.setattr(Path, "read_bytes", counted)
    return reads


def test_out_version_hashes_an_unchanged_manifest_once(tiny_out, tmp_path, monkeypatch):
    copy = tmp_path / "out"
    shutil.copytree(tiny_out, copy)
    manifest = copy / "manifest.json"
    hour_ago = time.time_ns() - 3600 * 10**9
    os.utime(manifest, ns=(hour_ago, hour_ago))
    reads = _read_counter(monkeypatch)
    first = dash.out_version(copy)
    assert [dash.out_version(copy) for _ in range(3)] == [first] * 3
    assert reads.count(manifest) == 1
    # the same size, its modification time put back: the change time still tells
    stat = manifest.stat()
    manifest.write_text(manifest.read_text().replace('"runs"', '"RUNS"', 1))
    os.utime(manifest, ns=(stat.st_atime_ns, stat.st_mtime_ns))
    assert manifest.stat().st_size == stat.st_size
    changed = dash.out_version(copy)
    assert changed != first
    assert changed == hashlib.sha256(manifest.read_bytes()).hexdigest()[:16]


def test_out_version_hashes_a_fresh_manifest_every_time(tiny_out, tmp_path, monkeypatch):
    copy = tmp_path / "out"
    shutil.copytree(tiny_out, copy)
    manifest = copy / "manifest.json"
    manifest.write_bytes(manifest.read_bytes())  # modified now: within the racy window
    reads = _read_counter(monkeypatch)
    assert dash.out_version(copy) == dash.out_version(copy) == dash.out_version(tiny_out)
    assert reads.count(manifest) == 2


def test_out_summary_counts(tiny_out):
    summary = dash.out_summary(tiny_out)
    episodes = va.episodes(tiny_out)
    assert summary.runs == 9
    assert summary.episodes == episodes.height == 9 * 24
    assert summary.steps == sql(tiny_out, "SELECT count(*) AS n FROM steps")["n"][0]


def test_input_path_falls_back_to_outs_parent(tmp_path, monkeypatch):
    (tmp_path / "bench").mkdir()
    out = tmp_path / "out"
    out.mkdir()
    monkeypatch.chdir("/")
    assert resolve_input(out, "bench") == tmp_path / "bench"
    assert resolve_input(out, "/abs/bench") == Path("/abs/bench")


# ---------------------------------------------------------------------- leaderboard


def test_best_rows_follow_each_metrics_direction():
    df = pl.DataFrame(
        {
            "SR": [10.0, 30.0, 30.0],
            "VSPS": [1.5, 0.5, None],
            "AvgDist": [None, None, None],
        }
    )
    best = dash.best_rows(df, ["SR", "VSPS", "AvgDist", "EIR"])
    assert best == {"SR": [1, 2], "VSPS": [1], "AvgDist": []}


def test_group_labels():
    df = pl.DataFrame({"run_id": ["r1", "r2"], "model": ["m", "m"], "n_goals": [1, None]})
    assert dash.group_labels(df, ["run_id", "model"]).to_list() == ["r1", "r2"]
    assert dash.group_labels(df, ["model"]).to_list() == ["m", "m"]
    assert dash.group_labels(df, ["model", "n_goals"]).to_list() == ["m · 1", "m · ∅"]
    assert dash.group_labels(df, []).to_list() == ["all", "all"]


def test_metrics_long_keeps_values_and_directions(tiny_out):
    table = va.metrics(tiny_out).with_columns(group=pl.col("run_id"))
    long = dash.metrics_long(table, ["SR", "VSPS"])
    assert long.height == 2 * table.height - table["VSPS"].null_count()
    row = long.filter((pl.col("group") == "sim-human") & (pl.col("metric") == "SR"))
    assert row["value"][0] == table.filter(pl.col("run_id") == "sim-human")["SR"][0]
    assert set(long["direction"]) == {"higher", "lower"}


# --------------------------------------------------------------------------- errors


def test_error_share_wide_rows_add_up(tiny_out):
    dist = error_distribution(tiny_out, labels=True).with_columns(group=pl.col("run_id"))
    wide = dash.error_share_wide(dist)
    assert wide["group"].to_list() == sorted(dist["run_id"].unique().to_list())
    shares = wide.drop("group", "errors")
    assert shares.width == 7
    for total in shares.sum_horizontal().to_list():
        assert total == pytest.approx(100.0)
    counts = dist.group_by("run_id").agg(pl.col("count").sum())
    assert dict(zip(wide["group"], wide["errors"], strict=True)) == dict(counts.iter_rows())


def test_switch_summary_joins_classes_and_ratios(tiny_out):
    classes = switch_classes(tiny_out).with_columns(group=pl.col("run_id"))
    ratios = va.metrics(tiny_out, metrics=["VSPS", "GVPE"]).with_columns(group=pl.col("run_id"))
    table = dash.switch_summary(classes, ratios)
    assert table.columns == ["group", "switches", "NP %", "PN %", "NN %", "PP %", "VSPS", "GVPE"]
    human = table.filter(pl.col("group") == "sim-human").row(0, named=True)
    n = sql(
        tiny_out,
        "SELECT count(*) AS n FROM steps WHERE run_id = 'sim-human' AND is_switch AND NOT truncated",
    )["n"][0]
    assert human["switches"] == n
    assert sum(human[f"{c} %"] for c in ("NP", "PN", "NN", "PP")) == pytest.approx(100.0)


def test_error_step_sample_is_the_head_of_steps_with_error(tiny_out):
    where = {"run_id": ["sim-vlm-a", "sim-vlm-b"]}
    every = va.steps_with_error(tiny_out, "invalid_coord", where=where)
    sample, total = dash.error_step_sample(
        tiny_out, "invalid_coord", where=where, columns=("run_id", "episode_id", "step"), limit=7
    )
    assert total == every.height > 7
    assert sample.rows() == every.select("run_id", "episode_id", "step").head(7).rows()


def test_first_rows_are_those_of_one_sorted_query(tiny_out):
    """The drill-downs read only the runs holding their first rows (`runs_holding_first`):
    the same rows and total as one query sorting every match, whatever the limit (inside a
    run, at a run's end, past every row, none)."""
    from vge_analytics.reports import ERROR_TYPES

    columns = ("run_id", "episode_id", "step", "error_type", "action_raw")
    for error_type in ERROR_TYPES:
        every = sql(
            tiny_out,
            "SELECT run_id, episode_id, step, error_type, action_raw FROM steps "
            f"WHERE NOT truncated AND error_type = '{error_type}' "
            "ORDER BY run_id, episode_id, step",
        )
        per_run = every.group_by("run_id", maintain_order=True).len()["len"].cum_sum()
        for limit in {0, 1, 7, *per_run.to_list()[:3], every.height, every.height + 5}:
            sample, total = dash.error_step_sample(tiny_out, error_type, {}, columns, limit=limit)
            assert total == every.height
            assert sample.rows() == every.head(limit).rows(), (error_type, limit)
    views = dash.interaction_views(tiny_out)
    for device_id, view in views.select("device_id", "view").head(4).iter_rows():
        clicks = sql(
            tiny_out,
            "SELECT run_id, episode_id, step, x, y FROM steps WHERE NOT truncated "
            f"AND is_interaction AND device_id = '{device_id}' AND view_before = '{view}' "
            "AND x IS NOT NULL AND y IS NOT NULL ORDER BY run_id, episode_id, step",
        )
        for limit in (0, 1, 5, clicks.height, clicks.height + 1):
            points = dash.click_points(tiny_out, device_id, view, limit=limit)
            got = points.select("run_id", "episode_id", "step", "x", "y").rows()
            assert got == clicks.head(limit).rows(), (device_id, view, limit)


# ------------------------------------------------------------------------ grounding


def test_click_points_are_the_interactions_of_a_view(tiny_out):
    views = dash.interaction_views(tiny_out)
    first = views.row(0, named=True)
    points = dash.click_points(tiny_out, first["device_id"], first["view"])
    assert points.height == first["interactions"]
    expected = sql(
        tiny_out,
        "SELECT count(*) FILTER (WHERE hit_target) AS t, "
        "count(*) FILTER (WHERE hit_component AND NOT hit_target) AS c, "
        "count(*) FILTER (WHERE NOT hit_component) AS m FROM steps "
        f"WHERE is_interaction AND NOT truncated AND device_id = '{first['device_id']}' "
        f"AND view_before = '{first['view']}'",
    ).row(0)
    counts = dash.click_counts(points)
    assert (counts["target hit"], counts["other component"], counts["miss"]) == expected
    assert (
        views["interactions"].sum()
        == sql(tiny_out, "SELECT count(*) AS n FROM steps WHERE is_interaction AND NOT truncated")[
            "n"
        ][0]
    )


def test_device_labels_most_clicked_first(tiny_out):
    views = dash.interaction_views(tiny_out)
    labels = dash.device_labels(views)
    totals = views.group_by("device_id").agg(pl.col("interactions").sum())
    expected = totals.sort(["interactions", "device_id"], descending=[True, False])
    assert sorted(labels) == sorted(expected["device_id"])
    first = next(iter(labels))
    assert first == views["device_id"][0]
    assert labels[first].endswith(f"{expected['interactions'].max()} clicks")


def test_click_points_filters(tiny_out):
    views = dash.interaction_views(tiny_out, where={"run_id": ["sim-human"]})
    first = views.row(0, named=True)
    points = dash.click_points(
        tiny_out, first["device_id"], first["view"], where={"run_id": ["sim-human"]}
    )
    assert set(points["run_id"]) == {"sim-human"}
    assert points.height == first["interactions"]


def test_scatter_boxes_mark_the_clicked_targets(tiny_out):
    first = dash.interaction_views(tiny_out).row(0, named=True)
    points = dash.click_points(tiny_out, first["device_id"], first["view"])
    targets = set(points["nearest_target"].drop_nulls())
    assert dash.clicked_targets(points) == tuple(sorted(targets))
    boxes = dash.scatter_boxes(tiny_out, first["device_id"], first["view"], sorted(targets))
    assert set(boxes.filter(pl.col("role") == "target")["component"]) == targets
    machine = dash.device_machine(tiny_out, first["device_id"])
    assert set(boxes["component"]) == {c for c, _ in machine.component_rects[first["view"]]}
    assert (boxes["x1"] > boxes["x0"]).all() and (boxes["y1"] > boxes["y0"]).all()


def test_view_boxes_targets_are_the_planners(tiny_out):
    steps = va.steps(
        tiny_out, where={"run_id": "sim-vlm-f", "is_interaction": True, "truncated": False}
    )
    row = steps.row(0, named=True)
    machine = dash.device_machine(tiny_out, row["device_id"])
    boxes = dash.view_boxes(
        machine,
        row["view_before"],
        state=row["state_before"],
        goal=row["goal_state"],
        hit=row["hit_components"],
    )
    s, g = machine.state_index[row["state_before"]], machine.state_index[row["goal_state"]]
    expected = {c for c, _ in replay.semantics.target_rects(machine, s, g, row["view_before"])}
    assert {b.component for b in boxes if b.role == "target"} == expected
    hits = {b.component for b in boxes if b.role == "hit"}
    assert hits == set(row["hit_components"]) - expected


# --------------------------------------------------------------------------- images


def test_draw_step_marks_click_and_boxes():
    blank = io.BytesIO()
    Image.new("RGB", (500, 250), (255, 255, 255)).save(blank, format="PNG")
    picture = dash.ViewPicture(blank.getvalue(), "png", 500, 250, rendered=True)
    boxes = [dash.Box("knob", 100, 100, 300, 500, role="target")]
    png = dash.draw_step(picture, boxes, (700.0, 600.0))
    img = Image.open(io.BytesIO(png)).convert("RGB")
    assert img.size == (500, 250)
    assert img.getpixel((350, 150)) == dash.CLICK_COLOR  # the x's centre: 700*0.5, 600*0.25
    assert img.getpixel((50, 50)) == dash.ROLE_COLORS["target"]  # the box's top-left corner


def test_step_picture_is_the_seen_view(tiny_out):
    row = va.steps(tiny_out, where={"run_id": "sim-vlm-f", "is_interaction": True}).row(
        0, named=True
    )
    png = dash.step_picture(tiny_out, "sim-vlm-f", row["episode_id"], row["step"])
    picture = dash.view_picture(tiny_out, row["device_id"], row["view_before"])
    assert picture.rendered  # the synthetic views are rendered on demand
    img = Image.open(io.BytesIO(png))
    assert img.width == min(picture.width, 720)


# ----------------------------------------------------------------------------- MCAP


def test_episode_mcap_on_demand_equals_the_replays_file(tiny_out, mcap_episode, tmp_path):
    run, episode = "sim-vlm-f", mcap_episode
    written = (tiny_out / "mcap" / run / f"{episode}.mcap").read_bytes()
    assert dash.episode_mcap(tiny_out, run, episode) == written
    copy = tmp_path / "out"
    shutil.copytree(tiny_out, copy, ignore=shutil.ignore_patterns("mcap"))
    assert dash.episode_mcap(copy, run, episode) == written


def test_episode_mcap_without_a_file(tiny_out, mcap_episode):
    from mcap.reader import make_reader

    episode = max(va.episodes(tiny_out, where={"run_id": "sim-human"})["episode_id"])
    assert episode != mcap_episode
    assert not (tiny_out / "mcap" / "sim-human" / f"{episode}.mcap").exists()
    data = dash.episode_mcap(tiny_out, "sim-human", episode)
    reader = make_reader(io.BytesIO(data))
    topics = {c.topic for c in reader.get_summary().channels.values()}
    assert {"/camera", "/annotations", "/step"} <= topics
    n_steps = va.episode_steps(tiny_out, "sim-human", episode).height
    assert reader.get_summary().statistics.channel_message_counts  # has messages
    steps = [m for _, c, m in reader.iter_messages(topics=["/step"])]
    assert len(steps) == n_steps


# ------------------------------------------------------------------- human vs VLM


def test_run_choices_human_first_best_model_first(tiny_out):
    runs = va.runs(tiny_out)
    refs, models = dash.run_choices(runs)
    assert refs[0] == "sim-human"
    assert "sim-human" not in models
    rates = {r["run_id"]: r["n_success"] / r["n_episodes"] for r in runs.iter_rows(named=True)}
    assert [rates[m] for m in models] == sorted((rates[m] for m in models), reverse=True)


def test_comparison_tables(tiny_out):
    cmp = compare(tiny_out, "sim-vlm-f", "sim-human", resamples=50)
    rows = dash.comparison_rows(cmp.metrics, "sim-vlm-f", "sim-human")
    assert rows.columns[:4] == ["metric", "sim-vlm-f", "sim-human", "sim-human − sim-vlm-f"]
    assert rows["metric"][0] == "SR ↑"
    assert rows["sim-human"].to_list() == cmp.metrics["B"].to_list()
    errors = dash.error_difference_rows(cmp.errors, "sim-vlm-f", "sim-human")
    assert errors["difference (pp)"].to_list() == cmp.errors["diff_pp"].to_list()
    flips = dash.flip_rows(cmp.flips, "sim-vlm-f", "sim-human")
    assert flips.height == cmp.flips.height
    for row in flips.iter_rows(named=True):
        assert {row["solved only by"], row["run_id"]} == {"sim-vlm-f", "sim-human"}
        failed = va.episodes(tiny_out, where={"run_id": row["run_id"]}).filter(
            pl.col("episode_id") == row["episode_id"]
        )
        assert failed["success"].to_list() == [False]


# -------------------------------------------------------------------- small helpers


def test_runs_matching(tiny_out):
    runs = va.runs(tiny_out)
    assert dash.runs_matching(runs, {}) == runs["run_id"].to_list()
    assert dash.runs_matching(runs, {"meta_history_length": ["3"]}) == ["sim-vlm-f-hist3"]
    assert dash.runs_matching(runs, {"category": ["Lamp"]}) == runs["run_id"].to_list()


def test_sweep_curves():
    table = pl.DataFrame(
        {
            "run_id": ["a", "a"],
            "model": ["m", "m"],
            "lambda": [2.0, 3.0],
            "SR": [10.0, 20.0],
            "SR_gain": [0.0, 10.0],
            "SR_rel_gain": [0.0, 100.0],
        }
    )
    assert dash.sweep_curves(table)["gain"].to_list() == [0.0, 10.0]
    assert dash.sweep_curves(table, relative=True)["gain"].to_list() == [0.0, 100.0]
    assert dash.sweep_curves(table).columns == ["group", "lambda", "SR", "gain"]


@pytest.fixture(scope="module")
def hand_examples_out(tmp_path_factory) -> Path:
    """The hand-worked runs (kettle cases a-g as `kettle-vlm`, dashboard cases a-e as
    `oven-human`; see tests/vge_analytics/metrics/test_metrics_hand.py) with values recorded
    by the harness on two kettle steps: case g's step 0 records feedback `null_effect` (the
    replay gives `transition`: it diverges) and state `LidOpen` (as replayed); case c's step
    1 records view `right` (as replayed). Recorded values never change the scoring."""
    root = tmp_path_factory.mktemp("examples")
    kettle = [_case(n) for n in KETTLE_CASES]
    oven = [_case(n) for n in OVEN_CASES]
    episodes = [copy.deepcopy(doc["episode"]) for doc in kettle]
    episodes[KETTLE_CASES.index("kettle_g_reset_chain")]["steps"][0].update(
        feedback="null_effect", state="LidOpen"
    )
    episodes[KETTLE_CASES.index("kettle_c_parse_multigoal_chain")]["steps"][1]["view"] = "right"
    bench = write_bench(root, kettle + oven)
    runs = [
        write_run(root, KETTLE_RUN, episodes),
        write_run(root, OVEN_RUN, [doc["episode"] for doc in oven]),
    ]
    return replay_to(root / "out", runs, bench)


EXAMPLE_ANSWERS = {
    # Oven: 5 of 5 succeed, L_act 8 + 9 + 5 + 8 + 2 = 32 -> 6.4. Kettle: 4 of 7 (57.14 %),
    # L_act 10 + 6 + 8 + 6 + 5 + 5 + 1 = 41 -> 5.857 -> 5.9.
    "Success rate and steps per model": [("model-o", 5, 100.0, 6.4), ("model-k", 7, 57.14, 5.9)],
    # Errors on scored steps. Oven: action_error a 3 + b 1 + d 2 = 6 beats switch_view_nn
    # (a 2, b 2, c 1 = 5). Kettle: action_error a 2 + c 3 = 5 beats component_selection,
    # params_error and invalid_coord (4 each).
    "Most common error per category": [
        ("Oven", "action_error", 6),
        ("ElectricKettle", "action_error", 5),
    ],
    # The failed episodes are kettle b, d and e; each was played by one run.
    "Episodes no run solved": [
        ("hw_kettle_b", "kettle", 1),
        ("hw_kettle_d", "kettle", 1),
        ("hw_kettle_e", "kettle", 1),
    ],
    # Every distance above 0 in the hand runs is above 200 (test_metrics_hand.py), with the
    # click and view the case notes give.
    "Clicks far from every target": [
        ("kettle-vlm", "hw_kettle_c", 4, "right", 1200.0, 90.0, 665.6),
        ("kettle-vlm", "hw_kettle_a", 6, "front", 780.0, 70.0, 627.6),
        ("kettle-vlm", "hw_kettle_f", 2, "front", 503.0, 297.0, 448.5),
        ("kettle-vlm", "hw_kettle_f", 3, "front", 498.0, 304.0, 444.6),
        ("kettle-vlm", "hw_kettle_d", 5, "top", 500.0, 300.0, 340.1),
        ("oven-human", "hw_dash_d", 5, "dashboard", 150.0, 175.0, 325.0),
    ],
    # Dangerous: kettle b steps 2 and 4, e 2, f 4; oven c 1. Scored steps: 41 and 32.
    "Dangerous actions per run": [("kettle-vlm", 4, 41), ("oven-human", 1, 32)],
    # Only the recorded feedback of kettle g differs from the replay.
    "Steps that diverge from the log": [
        ("kettle-vlm", "hw_kettle_g", 0, ["feedback"], "null_effect", "transition"),
    ],
}


@pytest.mark.parametrize("name", list(EXAMPLE_ANSWERS))
def test_example_queries_give_the_hand_answers(hand_examples_out, name):
    assert sql(hand_examples_out, dash.EXAMPLE_QUERIES[name]).rows() == EXAMPLE_ANSWERS[name]


def test_every_example_query_has_a_hand_answer(hand_examples_out):
    assert [*EXAMPLE_ANSWERS, "Run facets"] == list(dash.EXAMPLE_QUERIES)
    # Run facets: one row per run, sorted, with its counts and facets (45 kettle rows: the
    # 41 scored steps and 4 truncated ones, kettle b's and d's).
    facets = sql(hand_examples_out, dash.EXAMPLE_QUERIES["Run facets"])
    assert facets.select(
        "run_id", "model", "agent_kind", "lambda", "episodes", "steps", "diverged_steps",
        "meta_history", "meta_perturbation",
    ).rows() == [
        ("kettle-vlm", "model-k", "vlm", 5.0, 7, 45, 1, "full", "none"),
        ("oven-human", "model-o", "human", 5.0, 5, 32, 0, "3", "blur"),
    ]  # fmt: skip


def test_sql_preview_runs_in_its_own_process(tiny_out):
    limits = SqlLimits.make(memory="256MB", timeout=10)
    steps = sql(tiny_out, "SELECT count(*) AS n FROM steps")["n"][0]
    whole = dash.sql_preview(tiny_out, "SELECT step FROM steps ORDER BY ALL", steps, limits)
    assert whole.frame.height == steps and not whole.truncated
    assert whole.frame["step"].to_list() == sorted(
        sql(tiny_out, "SELECT step FROM steps")["step"].to_list()
    )
    cut = dash.sql_preview(tiny_out, "SELECT step FROM steps", 3, limits)
    assert cut.frame.height == 3 and cut.truncated
    assert dash.sql_caption(cut, 3).startswith("The first 3 rows (in ")
    assert dash.sql_caption(cut, 3).endswith(
        "the query has more. The page and the CSV download hold these 3 rows; "
        "`vge sql OUT QUERY --format csv` writes them all."
    )
    one = dash.sql_preview(tiny_out, "SELECT 1 AS one", 10, limits)
    assert re.fullmatch(
        r"1 row \(in \d+\.\d\d s, peak memory \d+(\.\d)? MB\)\.", dash.sql_caption(one, 10)
    )
    assert one.peak_memory > 10 * 1024**2  # the query's process, libraries loaded
    # Errors come back as the same one-line errors as in-process queries.
    with pytest.raises(va.QueryRefused, match="outside"):
        dash.sql_preview(tiny_out, "SELECT * FROM read_csv('/etc/passwd')", 10, limits)
    with pytest.raises(va.QueryRefused, match="read-only"):
        dash.sql_preview(tiny_out, "DROP VIEW steps", 10, limits)
    with pytest.raises(va.QueryError, match="no_such"):
        dash.sql_preview(tiny_out, "SELECT no_such FROM steps", 10, limits)
    assert dash.sql_limits_note(limits, 1000) == (
        "Each query runs in a process of its own and is stopped after 10 s or past 256 MB in "
        "memory, 512 MB on disk; the page shows the first 1,000 rows."
    )


def test_sql_preview_holds_a_bounded_result(tiny_out):
    """Wide rows come back cut by the query's process: text cells at 10,000 characters, the
    whole at RESULT_BYTES; the caption says what was cut."""
    limits = SqlLimits.make(memory="512MB", timeout=30)
    wide = dash.sql_preview(
        tiny_out, "SELECT repeat('x', 2000000) AS s FROM range(20)", 100, limits
    )
    assert wide.frame["s"].to_list() == ["x" * 10_000 + "… [cut: 1990000 more characters]"] * 20
    assert (wide.cut.cells, wide.cut.rows, wide.truncated) == (20, 0, False)
    mark = len("… [cut: 1990000 more characters]".encode())  # 34 bytes
    assert wide.cut.bytes == 20 * (2_000_000 - 10_000 - mark) == 39_799_320  # 37.96 MiB
    assert dash.sql_caption(wide, 100).startswith("20 rows shown (in ")
    assert dash.sql_caption(wide, 100).endswith(
        "38.0 MB cut to fit the page: 20 text cells longer than 10,000 characters cut (marked "
        "“… [cut: …]”). The page and the CSV download hold what is shown; "
        "`vge sql OUT QUERY --format csv` writes everything."
    )
    # 4 columns of 10,000 characters (cut from 10,001) and a mark of 28 bytes: 40,112 bytes
    # a row, so 32 MiB (33,554,432 bytes) hold 836 rows of the first 1,000
    columns = ", ".join(f"repeat('{c}', 10001) AS {c}" for c in "abcd")
    many = dash.sql_preview(tiny_out, f"SELECT {columns} FROM range(2000)", 1000, limits)
    row_bytes = 4 * (10_000 + len("… [cut: 1 more characters]".encode()))
    assert many.frame.height == va.store.RESULT_BYTES // row_bytes == 836
    assert (many.cut.cells, many.cut.rows, many.truncated) == (4000, 1000 - many.frame.height, True)
    assert dash.sql_caption(many, 1000).endswith(
        "4,000 text cells longer than 10,000 characters cut (marked “… [cut: …]”) and 164 rows "
        "past the page's 32 MB left out, and the query has more rows. The page and the CSV "
        "download hold what is shown; `vge sql OUT QUERY --format csv` writes everything."
    )


def test_csv_bytes_writes_lists_as_json():
    df = pl.DataFrame({"a": [1, 2], "b": [["x", "y"], []]})
    assert dash.csv_bytes(df).decode() == 'a,b\n1,"[""x"", ""y""]"\n2,[]\n'


def test_step_text(tiny_out):
    multi = va.episodes(tiny_out, where={"run_id": "sim-vlm-f"}).filter(
        (pl.col("n_goals") > 1) & (pl.col("L_act") > 1)
    )
    episode = multi["episode_id"][0]
    steps = va.episode_steps(tiny_out, "sim-vlm-f", episode)
    goals = va.goals(tiny_out, where={"run_id": "sim-vlm-f", "episode_id": episode})
    row = steps.row(1, named=True)
    text = dash.step_markdown(row, goals)
    assert row["action_raw"] in text
    assert f"({row['feedback_kind']})" in text
    assert goals["instruction"][row["goal_index"]] in text
    table = dash.step_classification(row)
    assert table["field"].to_list() == list(dash.CLASSIFICATION_FIELDS)
    blank = dash.step_classification(dict.fromkeys(dash.CLASSIFICATION_FIELDS))
    assert set(blank["value"]) == {MISSING}  # as the command line writes a null
    assert dash.termination_label("budget_local") == "local budget out"
    assert dash.termination_label("context_exceeded") == "context window full"
    # Every termination has its words (replay.semantics.TERMINATION_TEXTS), here and on the
    # Play page, where the log ends when the player gives up.
    labels = [dash.termination_label(t) for t in replay.TERMINATIONS]
    assert labels == ["success", "global budget out", "local budget out", "log ended",
                      "context window full"]  # fmt: skip
    assert result_headline("budget_global") == "Ended: the episode's step budget is spent"
    assert result_headline("context_exceeded") == "Ended: the model's context window is full"
    assert result_headline("log_ended") == "Ended by the player"
    assert result_headline("success") == "Success"


def test_episode_labels(tiny_out):
    episodes = va.episodes(tiny_out, where={"run_id": "sim-human"})
    labels = dash.episode_labels(episodes)
    assert list(labels) == episodes["episode_id"].to_list()
    row = episodes.row(0, named=True)
    assert labels[row["episode_id"]] == (
        f"{row['episode_id']} · {row['device_id']} · {dash.termination_label(row['termination'])}"
        f" · {row['goals_completed']}/{row['n_goals']} goals"
    )


# ----------------------------------------------------------------- metrics folders


def test_metric_headers_mark_overrides_and_additions(metrics_folder):
    chosen = va.load_metrics(metrics_folder)
    headers = dash.metric_headers(["SR", "SSR", "SR-multi", "VSPS"], chosen)
    assert headers == {"SR": "SR ↑ ✎", "SSR": "SSR ↑", "SR-multi": "SR-multi ↑ +", "VSPS": "VSPS ↓"}
    assert dash.metric_headers(["SR"]) == {"SR": "SR ↑"}  # the built-ins alone
    assert dash.metric_help("SR", chosen) == (
        "Success Rate with partial credit: SR that credits each completed goal: the mean of "
        f"goals_completed / n_goals. (overrides the built-in SR: {metrics_folder}/sr.sql, "
        "version 2)"
    )
    assert dash.metric_help("SR-multi", chosen).endswith(
        f"(added: {metrics_folder}/multi.sql, version 1)"
    )
    assert dash.metric_help("SSR", chosen).startswith("Sub-task Success Rate: Mean over")
    assert dash.metrics_note(chosen) == (
        f"Metrics of `{metrics_folder}`: ✎ overridden: SR; + added: SR-multi. Hover a header "
        "for its definition."
    )
    assert dash.metrics_note(va.MetricSet.builtin()) is None


def test_header_signs_are_in_the_installed_fonts():
    """The table is a canvas drawn with the system's fonts: a sign none of them has is an
    empty box (the full-width ＋ was one in Debian's Chromium). fontconfig, which Chromium
    draws through, names a font for each sign of the headers and of a missing value."""
    assert shutil.which("fc-list"), "fontconfig's fc-list is needed (Chromium depends on it)"
    signs = {c for mark in dash.ORIGIN_MARKS.values() for c in mark.strip()}
    signs |= {"↑", "↓", MISSING}
    for sign in sorted(signs):
        fonts = subprocess.run(
            ["fc-list", f":charset={ord(sign):x}", "family"],
            capture_output=True, text=True, check=True, timeout=60,
        ).stdout  # fmt: skip
        assert fonts.strip(), f"no installed font draws {sign!r} (U+{ord(sign):04X})"


def test_best_rows_of_an_added_metric(metrics_folder):
    chosen = va.load_metrics(metrics_folder)
    df = pl.DataFrame({"SR-multi": [50.0, 75.0, None]})
    assert dash.best_rows(df, ["SR-multi"], chosen) == {"SR-multi": [1]}
    with pytest.raises(va.UnknownMetricError):
        dash.best_rows(df, ["SR-multi"])  # not a built-in


def test_rescore_tables(tiny_out, metrics_folder):
    result = va.rescore(tiny_out, metrics_folder, by=("run_id", "model"))
    changes = dash.rescore_changes(result)
    assert changes.columns == [
        "metric", "group", "before", "after", "after − before", "rank before", "rank after",
        "move",
    ]  # fmt: skip
    assert changes["group"].to_list() == result.rows["run_id"].to_list()  # model left out
    assert changes["after − before"].to_list() == result.rows["delta"].to_list()
    rankings = dash.rescore_rankings(result)
    assert rankings["metric"].to_list() == ["SR", "SR-multi"]
    assert rankings["Kendall τ-b"][0] == result.summary["kendall_tau_b"][0]
    assert rankings["rank moved"][0] == ", ".join(result.summary["moved"][0])
    slopes = dash.rank_slopes(result, "SR")
    sr = result.rows.filter(pl.col("metric") == "SR")
    assert slopes.height == 2 * sr.height
    after = slopes.filter(pl.col("ranking") == "after")
    assert after["rank"].to_list() == sr["rank_after"].to_list()
    new = dash.rank_slopes(result, "SR-multi")  # no rank before: only the after points
    assert set(new["ranking"]) == {"after"}


def test_stored_sweeps_are_kept_per_metric_definitions(tiny_out, metrics_folder, tmp_path):
    runs = ["sim-human"]
    builtin = _sweep_cache_file(tiny_out, runs, [2, 3], None)
    overridden = _sweep_cache_file(tiny_out, runs, [2, 3], metrics_folder)
    assert builtin != overridden  # SR is defined differently: another stored sweep
    only_added = write_folder(tmp_path / "added", {"multi.sql": SR_MULTI})
    assert _sweep_cache_file(tiny_out, runs, [2, 3], only_added) == builtin
