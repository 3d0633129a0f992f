"""Kept answers (vge_analytics/commands/_answers.py; docs/METRICS.md, The metric cache): a
question `vge metrics OUT` answered once prints, asked again, byte for byte what it printed,
without computing; a change to OUT, to a metric file or to an option asks another question;
a bad file in the answer's place is answered again; the folder stays bounded."""

from __future__ import annotations

import io
import json
import os
import shutil
from pathlib import Path

import pytest
from rich.console import Console

from replay.io import METRIC_CACHE_DIR
from vge_analytics.commands import _answers, _output
from vge_analytics.commands import metrics as metrics_command
from vge_analytics.metrics import folder_fingerprint

from ..conftest import replay_to, write_run
from .test_cli import run

FORMATS = ("table", "json", "csv", "markdown", "latex")


def _answers_in(out: Path) -> list[Path]:
    return sorted((out / METRIC_CACHE_DIR).glob("answer-*.json"))


@pytest.fixture
def counted(monkeypatch) -> list[int]:
    """How many times a question was computed (not printed from a kept answer)."""
    calls: list[int] = []
    compute = metrics_command._answer

    def counting(*args, **kwargs):
        calls.append(1)
        return compute(*args, **kwargs)

    monkeypatch.setattr(metrics_command, "_answer", counting)
    return calls


@pytest.fixture
def mixed_out(pair, tmp_path_factory) -> Path:
    """The pair's two runs and a third whose run.json says it is incomplete: warning lines
    on stderr, marked rows."""
    root = tmp_path_factory.mktemp("mixed")
    header = {"run_id": "C", "model": "cut-sim", "agent_kind": "vlm", "lambda": 2}
    header["meta"] = {"complete": False, "infrastructure_failures": 1}
    episodes = [json.loads(line) for line in (pair["runs"][0] / "episodes.jsonl").open()]
    cut = write_run(root, header, episodes[:3])
    return replay_to(root / "out", [*pair["runs"], cut], pair["bench"])


QUESTIONS = [
    [],
    ["--by", "model"],
    ["--by", "agent_kind", "--metrics", "main"],
    ["--metrics", "SR,AvgDist"],
    ["--where", "run_id=A,C"],
    ["--where", "model=cut-sim,no-such-model"],  # a warning for the value no row holds
    ["--by", "episode_id", "--metrics", "SR"],  # a column of episodes: the tables answer
]


@pytest.mark.parametrize("fmt", FORMATS)
def test_an_answer_kept_is_printed_byte_for_byte(capsys, counted, mixed_out, tmp_path, fmt):
    out = tmp_path / "out"
    shutil.copytree(mixed_out, out)
    for question in QUESTIONS:
        args = ["metrics", str(out), "-f", fmt, *question]
        first = run(capsys, *args)
        assert first[0] == 0 and first[1], question
        assert ("no-such-model" in first[2]) == ("model=cut-sim,no-such-model" in question)
        before = len(counted)
        assert run(capsys, *args) == first, question
        assert len(counted) == before, question  # printed from the answer kept
    assert len(counted) == len(QUESTIONS)
    assert len(_answers_in(out)) == len(QUESTIONS)
    # The incomplete run is named on stderr each time, its rows marked.
    code, shown, err = run(capsys, "metrics", str(out), "-f", fmt)
    assert err.count("warning: run 'C' is incomplete") == 1
    assert ("(incomplete)" in shown) == (fmt not in ("json", "csv"))


def test_the_answer_is_what_the_tables_give(capsys, mixed_out, tmp_path):
    """Today's answer, computed on a copy that keeps nothing (its folder a link elsewhere,
    which no cache uses), is the answer kept and printed again."""
    kept, plain, elsewhere = tmp_path / "kept", tmp_path / "plain", tmp_path / "elsewhere"
    shutil.copytree(mixed_out, kept, ignore=shutil.ignore_patterns(METRIC_CACHE_DIR))
    shutil.copytree(mixed_out, plain, ignore=shutil.ignore_patterns(METRIC_CACHE_DIR))
    elsewhere.mkdir()
    (plain / METRIC_CACHE_DIR).symlink_to(elsewhere)
    for fmt in FORMATS:
        for question in QUESTIONS:
            today = run(capsys, "metrics", str(plain), "-f", fmt, *question)
            assert today[0] == 0
            for _ in range(2):
                assert run(capsys, "metrics", str(kept), "-f", fmt, *question) == today
    assert list(elsewhere.iterdir()) == []
    assert len(_answers_in(kept)) == len(FORMATS) * len(QUESTIONS)


def test_a_change_asks_again(capsys, counted, pair_out, tmp_path):
    out = tmp_path / "out"
    shutil.copytree(pair_out, out)
    folder = tmp_path / "mine"
    folder.mkdir()
    sql = (Path(metrics_command.__file__).parents[1] / "sql" / "sr.sql").read_text()
    (folder / "sr.sql").write_text(sql)
    args = ["metrics", str(out), "--metrics-dir", str(folder), "-f", "markdown"]
    first = run(capsys, *args)
    assert run(capsys, *args) == first and len(counted) == 1
    # a metric file changed: its direction decides the marks of the table
    (folder / "sr.sql").write_text(sql.replace("-- direction: higher", "-- direction: lower"))
    changed = run(capsys, *args)
    assert changed != first and len(counted) == 2
    # an option changed
    run(capsys, *args, "--by", "model")
    assert len(counted) == 3
    # OUT changed: a table file touched (its modification time is in the key of OUT's contents)
    part = next((out / "episodes").rglob("*.parquet"))
    os.utime(part, ns=(part.stat().st_atime_ns, part.stat().st_mtime_ns + 1_000_000))
    assert run(capsys, *args) == changed
    assert len(counted) == 4
    # ...and the answers kept for the contents before are gone
    assert len(_answers_in(out)) == 1
    assert run(capsys, *args) == changed and len(counted) == 4


def test_the_question_holds_everything_that_decides_the_answer(monkeypatch, pair_out):
    builtins = folder_fingerprint(None)
    assert builtins == "built-in"
    options = {"out": str(pair_out), "by": "run_id,model", "fmt": "table"}
    key = _answers.question_key("metrics", options, builtins)
    assert key == _answers.question_key("metrics", dict(options), builtins)
    assert key != _answers.question_key("metrics", {**options, "by": "model"}, builtins)
    assert key != _answers.question_key("errors", options, builtins)
    traits = _output.console_traits()
    monkeypatch.setattr(_answers, "console_traits", lambda: {**traits, "width": 80})
    assert key != _answers.question_key("metrics", options, builtins)  # a narrower terminal
    json_key = _answers.question_key("metrics", {**options, "fmt": "json"}, builtins)
    monkeypatch.setattr(_answers, "code_key", lambda: "another version")
    assert json_key != _answers.question_key("metrics", {**options, "fmt": "json"}, builtins)


def test_a_metrics_folder_is_told_by_its_files(tmp_path):
    """`folder_fingerprint`: the folder as given, and each metric file's name and text; None
    where `load_metrics` would find a problem reading it."""
    folder = tmp_path / "mine"
    folder.mkdir()
    assert folder_fingerprint(folder) is None  # no metric file
    sql = (Path(metrics_command.__file__).parents[1] / "sql" / "sr.sql").read_text()
    (folder / "sr.sql").write_text(sql)
    (folder / "README.md").write_text("not a metric file")
    told = folder_fingerprint(folder)
    assert told is not None and told == folder_fingerprint(str(folder))
    (folder / "README.md").write_text("still not one")
    assert folder_fingerprint(folder) == told
    (folder / "sr.sql").write_text(sql + "\n")
    assert folder_fingerprint(folder) not in (None, told)
    os.mkfifo(folder / "fifo.sql")
    assert folder_fingerprint(folder) is None
    assert folder_fingerprint(tmp_path / "missing") is None


@pytest.mark.parametrize(
    "bad",
    ["garbage", "deep", "wrong shape", "other format", "too large", "a folder", "a fifo", "a link"],
)
def test_a_bad_answer_file_is_answered_again(capsys, counted, monkeypatch, pair_out, tmp_path, bad):
    out = tmp_path / "out"
    shutil.copytree(pair_out, out)
    args = ["metrics", str(out), "-f", "csv"]
    first = run(capsys, *args)
    (path,) = _answers_in(out)
    doc = json.loads(path.read_text())
    path.unlink()
    if bad == "garbage":
        path.write_bytes(b"\xff\x00{not json")
    elif bad == "deep":  # JSON nested deeper than Python's stack
        path.write_text("[" * 200_000 + "]" * 200_000)
    elif bad == "wrong shape":
        path.write_text(json.dumps({**doc, "text": 3}))
    elif bad == "other format":
        path.write_text(json.dumps({**doc, "format": _answers.ANSWER_FORMAT + 1, "text": "x"}))
    elif bad == "too large":
        monkeypatch.setattr(_answers, "MAX_ANSWER_BYTES", 16)
        path.write_text(json.dumps(doc))
    elif bad == "a folder":
        path.mkdir()
    elif bad == "a fifo":
        os.mkfifo(path)
    else:  # a link to a file that holds an answer (planted: not read through)
        planted = tmp_path / "planted.json"
        planted.write_text(json.dumps({**doc, "text": "planted\n"}))
        path.symlink_to(planted)
    assert run(capsys, *args) == first
    assert len(counted) == 2


def test_nothing_is_kept_through_a_link(capsys, counted, pair_out, tmp_path):
    out, elsewhere = tmp_path / "out", tmp_path / "elsewhere"
    shutil.copytree(pair_out, out, ignore=shutil.ignore_patterns(METRIC_CACHE_DIR))
    elsewhere.mkdir()
    (out / METRIC_CACHE_DIR).symlink_to(elsewhere)
    first = run(capsys, "metrics", str(out), "-f", "json")
    assert run(capsys, "metrics", str(out), "-f", "json") == first
    assert len(counted) == 2 and list(elsewhere.iterdir()) == []


def test_the_answers_kept_are_bounded(capsys, counted, monkeypatch, pair_out, tmp_path):
    out = tmp_path / "out"
    shutil.copytree(pair_out, out)
    monkeypatch.setattr(_answers, "MAX_ANSWERS", 3)
    for i, fmt in enumerate(FORMATS):
        run(capsys, "metrics", str(out), "-f", fmt)
        assert len(_answers_in(out)) == min(i + 1, 3)
    run(capsys, "metrics", str(out), "-f", "latex")  # the newest three are kept
    run(capsys, "metrics", str(out), "-f", "table")
    assert len(counted) == len(FORMATS) + 1
    monkeypatch.setattr(_answers, "MAX_ANSWER_BYTES", 64)  # an answer too large is not kept
    run(capsys, "metrics", str(out), "-f", "json", "--by", "model")
    run(capsys, "metrics", str(out), "-f", "json", "--by", "model")
    assert len(counted) == len(FORMATS) + 3


def test_an_answer_computed_while_out_changed_is_not_kept(capsys, monkeypatch, pair_out, tmp_path):
    out = tmp_path / "out"
    shutil.copytree(pair_out, out)
    compute = metrics_command._answer
    part = next((out / "steps").rglob("*.parquet"))

    def changing(*args, **kwargs):
        answer = compute(*args, **kwargs)
        os.utime(part, ns=(part.stat().st_atime_ns, part.stat().st_mtime_ns + 1_000_000))
        return answer

    monkeypatch.setattr(metrics_command, "_answer", changing)
    assert run(capsys, "metrics", str(out), "-f", "json")[0] == 0
    assert _answers_in(out) == []


def test_an_answer_computed_while_a_metric_file_changed_is_not_kept(
    capsys, monkeypatch, pair_out, tmp_path
):
    out, folder = tmp_path / "out", tmp_path / "mine"
    shutil.copytree(pair_out, out)
    folder.mkdir()
    sql = (Path(metrics_command.__file__).parents[1] / "sql" / "sr.sql").read_text()
    (folder / "sr.sql").write_text(sql)
    compute = metrics_command._answer

    def changing(*args, **kwargs):
        answer = compute(*args, **kwargs)
        (folder / "sr.sql").write_text(sql.replace("-- direction: higher", "-- direction: lower"))
        return answer

    monkeypatch.setattr(metrics_command, "_answer", changing)
    assert run(capsys, "metrics", str(out), "--metrics-dir", str(folder))[0] == 0
    assert _answers_in(out) == []


@pytest.mark.parametrize(
    "console",
    [
        {"width": 400},
        {"width": 60},
        {"width": 120, "force_terminal": True, "color_system": "truecolor"},
        {"width": 100, "force_terminal": True, "color_system": "standard"},
    ],
)
def test_a_table_captured_is_the_table_printed(monkeypatch, pair_out, console):
    """The table format is kept as the console renders it: the same bytes its `print`
    writes, on any width and colours."""
    import vge_analytics as va

    df = va.metrics(pair_out)
    printed_to = io.StringIO()
    made = {"highlight": False, "soft_wrap": False, **console}
    monkeypatch.setattr(_output, "_console", lambda: Console(file=printed_to, **made))
    shown = _output.printed(df, "table", title="The paper's metrics")
    assert shown.console and printed_to.getvalue() == ""
    from vge_analytics import reports

    Console(file=printed_to, **made).print(reports.render(df, "table", title="The paper's metrics"))
    assert shown.text == printed_to.getvalue()
