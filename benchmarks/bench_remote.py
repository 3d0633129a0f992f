"""The analytics over an OUT in object storage against the same OUT on the local disk (not a
test): an S3-compatible server (moto) on 127.0.0.1, so the network cost is the HTTP and the
server's, not a data centre's.

Usage (moto comes with the `test` extra):

    vge demo                                   # ./logs-replayed
    .venv/bin/python benchmarks/bench_remote.py logs-replayed [--repeats 5]

OUT is uploaded once (without `.replay/`); then `va.metrics` (all twelve metrics per run)
and `va.error_distribution` are timed on the local directory and on `s3://...`, both cold
(the first call: opening the store, reading the manifest and the Parquet footers) and warm
(later calls on the cached store; median of `--repeats`). The results are asserted equal.
"""

from __future__ import annotations

import argparse
import logging
import os
import statistics
import time
from pathlib import Path

import pyarrow.fs as pafs

import vge_analytics as va

TEST_CREDENTIALS = {
    "AWS_ACCESS_KEY_ID": "testing",
    "AWS_SECRET_ACCESS_KEY": "testing",
    "AWS_DEFAULT_REGION": "us-east-1",
    "AWS_EC2_METADATA_DISABLED": "true",
}


def suite(out: str) -> tuple:
    return va.metrics(out), va.error_distribution(out, ["run_id"])


def timed(out: str, repeats: int) -> tuple[float, float, tuple]:
    va.clear_cache()
    started = time.perf_counter()
    result = suite(out)
    cold = time.perf_counter() - started
    warm = []
    for _ in range(repeats):
        started = time.perf_counter()
        suite(out)
        warm.append(time.perf_counter() - started)
    return cold, statistics.median(warm), result


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", type=Path, help="a replay output directory")
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()
    os.environ.update(TEST_CREDENTIALS)
    from moto.server import ThreadedMotoServer

    logging.getLogger("werkzeug").setLevel(logging.ERROR)  # one line per request otherwise

    server = ThreadedMotoServer(ip_address="127.0.0.1", port=0, verbose=False)
    server.start()
    try:
        host, port = server.get_host_and_port()
        query = f"endpoint_override=http://{host}:{port}&scheme=http&region=us-east-1"
        fs, _ = pafs.FileSystem.from_uri(f"s3://bench?{query}&allow_bucket_creation=true")
        fs.create_dir("bench")
        local = args.out.resolve()
        for child in sorted(local.iterdir()):
            if child.name == ".replay":
                continue
            target = f"bench/out/{child.name}"
            if child.is_dir():
                pafs.copy_files(str(child), target, destination_filesystem=fs)
            else:
                with fs.open_output_stream(target) as sink:
                    sink.write(child.read_bytes())
        remote = f"s3://bench/out?{query}"
        steps = int(va.sql(local, "SELECT count(*) AS n FROM steps")["n"][0])
        rows = []
        results = []
        for name, where in (("local disk", str(local)), ("S3 (moto, 127.0.0.1)", remote)):
            cold, warm, result = timed(where, args.repeats)
            rows.append((name, cold, warm))
            results.append(result)
        for a, b in zip(*results, strict=True):
            assert a.equals(b), "the remote OUT gave other numbers"
        print(f"{local}: {steps:,} steps; metrics + error distribution per run")
        print(f"{'OUT':<22} {'cold s':>8} {'warm s':>8}")
        for name, cold, warm in rows:
            print(f"{name:<22} {cold:>8.3f} {warm:>8.3f}")
        print(
            f"ratio S3/local: cold {rows[1][1] / rows[0][1]:.1f}x, warm {rows[1][2] / rows[0][2]:.1f}x"
        )
    finally:
        va.clear_cache()
        server.stop()


if __name__ == "__main__":
    main()
