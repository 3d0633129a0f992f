"""Fixtures of the input/output tests: an S3-compatible server on 127.0.0.1; a crash on\ndemand."""

from __future__ import annotations

import os

import pyarrow.fs as pafs
import pytest

S3_TEST_ENV = {
    "AWS_ACCESS_KEY_ID": "testing",
    "AWS_SECRET_ACCESS_KEY": "testing",
    "AWS_DEFAULT_REGION": "us-east-1",
    "AWS_EC2_METADATA_DISABLED": "true",
}
"""Credentials the test server accepts (any), set in the environment as on a real cluster
(worker processes and Ray workers inherit them); no instance-metadata lookups."""


@pytest.fixture(scope="module")
def s3_server():
    """A moto S3 server on 127.0.0.1 (an ephemeral port, real HTTP) with a bucket `vge`,
    test credentials in the environment; yields pyarrow's S3FileSystem on it and the URI
    query that points a URI at it (`s3://vge/...?{query}`). Stopped at the end."""
    from moto.server import ThreadedMotoServer

    saved = {k: os.environ.get(k) for k in S3_TEST_ENV}
    os.environ.update(S3_TEST_ENV)
    server = ThreadedMotoServer(ip_address="127.0.0.1", port=0, verbose=False)
    server.start()
    host, port = server.get_host_and_port()
    query = f"endpoint_override=http://{host}:{port}&scheme=http&region=us-east-1"
    fs, _ = pafs.FileSystem.from_uri(f"s3://vge?{query}&allow_bucket_creation=true")
    fs.create_dir("vge")
    yield fs, query
    del fs
    server.stop()
    for k, v in saved.items():
        if v is None:
            os.environ.pop(k, None)
        else:
            os.environ[k] = v


def fail_after(monkeypatch: pytest.MonkeyPatch, target: object, name: str, n: int) -> None:
    """`target.name` works `n` times, then raises `OSError("simulated crash")`."""
    real = getattr(target, name)
    calls = {"n": 0}

    def failing(*args, **kwargs):
        calls["n"] += 1
        if calls["n"] > n:
            raise OSError("simulated crash")
        return real(*args, **kwargs)

    monkeypatch.setattr(target, name, failing)
