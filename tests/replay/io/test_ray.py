"""Replay and sweeps on a real Ray cluster: two raylets on loopback (`ray.cluster_utils`).

The output directory must be byte-identical to a local replay, whatever ran where; tasks
must have run on both nodes; a worker killed mid-run (its task retried by Ray) must change
nothing.
"""

from __future__ import annotations

import hashlib
import os
import sys
from pathlib import Path

# Keep every node on loopback: without this Ray advertises the host's network address.
os.environ["RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER"] = "0"

import pyarrow.fs as pafs  # noqa: E402
import pytest  # noqa: E402
import ray  # noqa: E402
from ray.cluster_utils import Cluster  # noqa: E402

import replay  # noqa: E402
import vge_analytics as va  # noqa: E402
from replay.io._ray import FAULT_ENV, RayCluster  # noqa: E402
from vge_analytics.cli import _fill_optional_values  # noqa: E402

from .conftest import S3_TEST_ENV  # noqa: E402

ROOT = Path(__file__).resolve().parents[3]
LOGS = ROOT / "logs"
RUNS = sorted(str(p) for p in (LOGS / "runs").iterdir() if p.is_dir())

pytestmark = pytest.mark.xdist_group("ray")


@pytest.fixture(scope="module")
def crash_marker(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return tmp_path_factory.mktemp("chaos") / "killed-once"


@pytest.fixture(scope="module")
def cluster(crash_marker: Path):
    """Two nodes of one CPU each on 127.0.0.1; the first batch task kills its own worker
    process once (FAULT_ENV), which Ray must survive by running the task again."""
    os.environ[FAULT_ENV] = str(crash_marker)  # inherited by the raylets and their workers
    os.environ.update(S3_TEST_ENV)  # object storage credentials, as a real cluster's nodes have
    head = {"num_cpus": 1, "node_ip_address": "127.0.0.1", "include_dashboard": False}
    c = Cluster(initialize_head=True, head_node_args=head)
    c.add_node(num_cpus=1, node_ip_address="127.0.0.1")
    ray.init(address=c.address, log_to_driver=False)
    c.wait_for_nodes()
    yield c
    ray.shutdown()
    c.shutdown()
    del os.environ[FAULT_ENV]


def _digests(out: Path) -> dict[str, str]:
    return {
        str(p.relative_to(out)): hashlib.sha256(p.read_bytes()).hexdigest()
        for p in sorted(out.rglob("*"))
        if p.is_file() and ".replay" not in p.parts
    }


@pytest.fixture(scope="module")
def local_out(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("local") / "out"
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr("replay.io._job.BATCH_LINES", 64)
        replay.replay_runs(RUNS, LOGS / "bench", out, progress=False)
    return out


def test_replay_on_two_nodes_is_byte_identical(
    cluster, local_out: Path, crash_marker: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr("replay.io._job.BATCH_LINES", 64)  # many tasks: both nodes busy
    out = tmp_path / "out"
    manifest = replay.replay_runs(RUNS, LOGS / "bench", out, ray="auto", progress=False)
    assert _digests(out) == _digests(local_out)
    assert manifest.exit_code == 0
    # every batch ran once to the end (the killed attempt is not counted), on both nodes
    alive = {n["NodeID"] for n in ray.nodes() if n["Alive"]}
    assert set(manifest.nodes) == alive and len(alive) == 2
    batches = sum(-(-r.counts.lines_read // 64) for r in manifest.runs)  # 64 lines each
    assert sum(manifest.nodes.values()) == batches
    assert crash_marker.exists()  # a worker process was killed mid-run and its task retried


def test_replay_on_two_nodes_into_object_storage(
    cluster, s3_server, local_out: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """OUT in an S3 bucket (moto on 127.0.0.1): every node writes its parts there; the
    bucket then holds the same files as the local replay."""
    monkeypatch.setattr("replay.io._job.BATCH_LINES", 64)
    fs, query = s3_server
    manifest = replay.replay_runs(
        RUNS, LOGS / "bench", f"s3://vge/ray-out?{query}", ray="auto", progress=False
    )
    assert len(manifest.nodes) == 2
    pafs.copy_files("vge/ray-out", str(tmp_path / "got"), source_filesystem=fs)
    assert _digests(tmp_path / "got") == _digests(local_out)


def test_sweep_on_the_cluster_equals_the_local_sweep(cluster, local_out: Path) -> None:
    local = va.sweep(local_out, [2, 3, 5], metrics=["SR", "SSR", "SPL"])
    on_ray = va.sweep(local_out, [2, 3, 5], metrics=["SR", "SSR", "SPL"], ray="auto")
    assert on_ray.equals(local)
    assert local.height == 3 * len(RUNS)


def test_ray_not_installed_is_one_line(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(sys.modules, "ray", None)  # `import ray` fails as if not installed
    with pytest.raises(replay.ConfigError, match=r"pip install 'vge-analytics\[ray\]'"):
        RayCluster("auto")


def test_ray_option_value_may_be_left_out(tmp_path: Path) -> None:
    run = tmp_path / "run"
    run.mkdir()
    assert _fill_optional_values(["replay", str(run), "--ray"]) == [
        "replay",
        str(run),
        "--ray",
        "auto",
    ]
    assert _fill_optional_values(["replay", "--ray", str(run), "--out", "o"]) == [
        "replay",
        "--ray",
        "auto",
        str(run),
        "--out",
        "o",
    ]
    assert _fill_optional_values(["replay", "--ray", "--workers", "2"])[:3] == [
        "replay",
        "--ray",
        "auto",
    ]
    assert _fill_optional_values(["replay", "--ray", "local", "x"]) == [
        "replay",
        "--ray",
        "local",
        "x",
    ]
