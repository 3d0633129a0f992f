"""The bundled sample: sim-vlm-a continued by `sim:f` from its first error with the fix
(PROTOCOL §10.4). The continuation replays with no divergent step; its prefix steps are the
source's responses, cut exactly before each episode's first error; every fix is the planner's
step there (§4.5) and every fix that operates the device made progress. A fix can also be a
view switch (the plan's next interaction is in another view): a switch makes no progress by
§5.1, and it moves to a view showing a target (NP), or to the view holding the dashboard
region on the way to a target on the locked dashboard (NN)."""

from __future__ import annotations

from pathlib import Path

import msgspec
import pytest

import replay
import vge_analytics as va
from vge_analytics.cli import main

LOGS = Path(__file__).resolve().parents[3] / "logs"


@pytest.fixture(scope="module")
def continued(tmp_path_factory: pytest.TempPathFactory) -> Path:
    root = tmp_path_factory.mktemp("sample")
    cont = root / "cont"
    args = [
        "run",
        str(LOGS / "bench"),
        "--agent",
        "sim:f",
        "--from",
        str(LOGS / "runs" / "sim-vlm-a"),
    ]
    assert main([*args, "--at", "first-error", "--fix", "--out", str(cont), "--no-progress"]) == 0
    out = root / "out"
    manifest = replay.replay_runs(
        [cont, LOGS / "runs" / "sim-vlm-a"], LOGS / "bench", out, progress=False
    )
    counts = manifest.run("cont").counts
    assert (counts.replayed, counts.quarantined, counts.diverged_steps) == (312, 0, 0)
    assert manifest.run("cont").divergence.steps_compared == counts.steps - counts.truncated_steps
    return out


def test_the_prefix_repeats_the_source_up_to_its_first_error(continued: Path) -> None:
    same = va.sql(
        continued,
        "SELECT count(*) AS n, count(*) FILTER (WHERE c.output IS NOT DISTINCT FROM s.output "
        "AND c.action_raw = s.action_raw AND c.state_after = s.state_after) AS same "
        "FROM steps AS c JOIN steps AS s ON s.run_id = 'sim-vlm-a' "
        "AND s.episode_id = c.episode_id AND s.step = c.step "
        "WHERE c.run_id = 'cont' AND c.origin = 'prefix'",
    ).row(0, named=True)
    cut = va.sql(
        continued,
        "WITH first_error AS (SELECT episode_id, min(step) AS k FROM steps "
        "WHERE run_id = 'sim-vlm-a' AND error_type IS NOT NULL GROUP BY episode_id) "
        "SELECT count(*) AS n, count(*) FILTER (WHERE e.prefix_steps = f.k) AS at_error, "
        "sum(e.prefix_steps) AS prefix, count(*) FILTER (WHERE e.fixed AND e.continued) AS fixed "
        "FROM episodes AS e JOIN first_error AS f USING (episode_id) WHERE e.run_id = 'cont'",
    ).row(0, named=True)
    # Every episode of sim-vlm-a has an error: all 312 are cut, fixed and continued.
    assert (cut["n"], cut["at_error"], cut["fixed"]) == (312, 312, 312)
    assert same["n"] == same["same"] == cut["prefix"] > 0


def test_every_fix_is_the_planners_step_and_operating_fixes_made_progress(
    continued: Path,
) -> None:
    fixes = va.sql(
        continued,
        "SELECT episode_id, step, action_type, x, y, params, progress, switch_class, "
        "dashboard_unlocked FROM steps WHERE run_id = 'cont' AND origin = 'fix' "
        "ORDER BY episode_id",
    ).to_dicts()
    assert len(fixes) == 312 and all(f["step"] >= 0 for f in fixes)
    operating = [f for f in fixes if f["action_type"] != "switch_view"]
    switches = [f for f in fixes if f["action_type"] == "switch_view"]
    assert operating and all(f["progress"] for f in operating)
    assert all(not f["progress"] for f in switches)
    assert all(
        f["switch_class"] == "NP"
        or (f["switch_class"] == "NN" and f["dashboard_unlocked"] is False)
        for f in switches
    )

    # Each fix is the optimal next step from where the source's prefix left the episode.
    bench = replay.Benchmark.open(LOGS / "bench")
    source = {
        e["episode_id"]: e
        for e in va.episodes(
            continued, where={"run_id": "sim-vlm-a"}, columns=["episode_id", "lambda"]
        ).to_dicts()
    }
    logs = {
        log.episode_id: log
        for _, line in replay.io.iter_lines(replay.episodes_file(LOGS / "runs" / "sim-vlm-a"))
        for log in [msgspec.json.decode(line, type=replay.EpisodeLog)]
    }
    for f in fixes[::13]:  # a sample of them: each replays its prefix
        task = bench.tasks[f["episode_id"]].task
        machine = bench.machine(task.device_id)
        session = replay.EpisodeSession(
            machine,
            task,
            lam=source[f["episode_id"]]["lambda"],
            run_id="",
            model="",
            agent_kind="vlm",
        )
        for step in logs[f["episode_id"]].steps[: f["step"]]:
            session.advance(step)
        sim = session.sim
        planned = replay.next_optimal_step(
            machine, sim.state, sim.view, sim.unlocked, tuple(session.goals[session.current :])
        )
        assert planned is not None and planned.action.type == f["action_type"]
        assert (
            planned.action.coord == (None if f["x"] is None else (f["x"], f["y"]))
            and list(planned.action.params) == f["params"]
        )
