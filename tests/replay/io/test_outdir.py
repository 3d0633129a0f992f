"""`run_inputs`: the inputs of a run as the manifest records them, the SSMs of a replay's
runs referenced once for all of them."""

from __future__ import annotations

import hashlib
from pathlib import Path

import pytest

from replay.io import _outdir
from replay.io._manifest import FileRef, Hasher
from replay.io._reading import read_runs

from ..conftest import Sample


def _devices(bench: Path) -> list[str]:
    return sorted(p.name.removesuffix(".json") for p in (bench / "ssm").glob("*.json"))


def test_the_runs_of_a_replay_share_their_ssm_references(
    copy_sample: Sample, monkeypatch: pytest.MonkeyPatch
) -> None:
    vlm, human = read_runs([str(copy_sample.vlm), str(copy_sample.human)])
    bench = str(copy_sample.bench)
    devices = [*_devices(copy_sample.bench), "../outside"]  # a name no file may have
    confinements = []
    real = _outdir.confinement
    monkeypatch.setattr(
        _outdir, "confinement", lambda root: confinements.append(root) or real(root)
    )
    hasher = Hasher()
    first = _outdir.run_inputs(vlm, bench, hasher, devices)
    second = _outdir.run_inputs(human, bench, hasher, devices)
    alone = _outdir.run_inputs(human, bench, Hasher(), devices)

    assert len(confinements) == 2  # the second run resolved no SSM again; the fresh one did
    assert second == alone  # the same record as a replay of that run alone
    assert second.ssm == first.ssm and list(second.ssm) == devices[:-1]  # the bad name: none
    some = devices[0]
    path = copy_sample.bench / "ssm" / f"{some}.json"
    assert second.ssm[some] == FileRef(str(path), hashlib.sha256(path.read_bytes()).hexdigest())
    assert second.ssm[some] is first.ssm[some]
