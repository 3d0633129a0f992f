"""Metric files: the format of the built-ins, read from a user's folder. Every kind of
malformed file gives its one line naming the file and the line, and exit code 1; nothing is
dropped silently."""

from __future__ import annotations

from importlib import resources
from pathlib import Path

import pytest

import vge_analytics as va
from vge_analytics.cli import main
from vge_analytics.metrics._check import check_metric
from vge_analytics.metrics._file import parse_metric_file

from .metric_files import SR_MULTI, metric_text, write_folder

# metric_text's layout: 1 metric, 2 title, 3 direction, 4 unit, 5 grain, 6 version,
# 7 definition, 8 blank, 9 `-- numerator`, 10 numerator, 11 blank, 12 `-- denominator`,
# 13 denominator.
GOOD = metric_text("X", "count(*) FILTER (WHERE success)", "count(*)")


def _numerator(sql: str, **fields) -> str:
    return metric_text("X", sql, "count(*)", **fields)


MALFORMED = {
    # kind: (file text, line, what the message says)
    "unknown header key": (
        GOOD.replace("\n\n-- numerator", "\n-- colour: red\n\n-- numerator"),
        8,
        "unknown header key 'colour' (known: metric, title, direction, unit, grain, version, "
        "definition, level, null)",
    ),
    "header key given twice": (
        GOOD.replace("-- grain: episodes\n", "-- grain: episodes\n-- unit: ratio\n"),
        6,
        "header key 'unit' given twice (first at line 4)",
    ),
    "missing header key": (
        GOOD.replace("-- title: X\n", ""),
        1,
        "missing header key title (required: metric, title, direction, unit, grain, version, "
        "definition)",
    ),
    "missing numerator": (
        GOOD.replace("-- numerator\ncount(*) FILTER (WHERE success)\n", ""),
        11,
        "no '-- numerator' section (the metric's numerator)",
    ),
    "missing denominator": (
        GOOD.replace("-- denominator\ncount(*)\n", ""),
        11,
        "no '-- denominator' section (the metric's denominator)",
    ),
    "empty numerator": (
        GOOD.replace("count(*) FILTER (WHERE success)\n", "-- nothing yet\n"),
        9,
        "the numerator is empty (no SQL after it)",
    ),
    "second numerator": (
        GOOD + "\n-- numerator\ncount(*)\n",
        15,
        "a second '-- numerator' line (one numerator per file)",
    ),
    "SQL before the sections": (
        GOOD.replace("\n\n-- numerator", "\ncount(*)\n\n-- numerator"),
        8,
        "SQL before the '-- numerator' line (the header holds '-- key: value' lines only)",
    ),
    "header after the sections": (
        GOOD + "-- direction: lower\n",
        14,
        "header line '-- direction:' after the SQL sections (the header comes first)",
    ),
    "unknown grain": (
        metric_text("X", "count(*)", "count(*)", grain="runs"),
        5,
        "unknown grain 'runs' (one of: episodes, steps, goals)",
    ),
    "unknown direction": (
        metric_text("X", "count(*)", "count(*)", direction="up"),
        3,
        "unknown direction 'up' (one of: higher, lower)",
    ),
    "direction in capitals": (
        metric_text("X", "count(*)", "count(*)", direction="Higher"),
        3,
        "unknown direction 'Higher' (one of: higher, lower); did you mean 'higher'?",
    ),
    "unknown unit": (
        metric_text("X", "count(*)", "count(*)", unit="pct"),
        4,
        "unknown unit 'pct' (one of: percent, ratio, distance)",
    ),
    "unknown level": (
        GOOD.replace("-- version: 1\n", "-- version: 1\n-- level: per-run\n"),
        7,
        "unknown level 'per-run' (one of: episode-mean, step-ratio, run-level ratio, "
        "goal-ratio)",
    ),
    "version not a number": (
        GOOD.replace("-- version: 1", "-- version: v2"),
        6,
        "version 'v2' is not a whole number of at least 1",
    ),
    "not a metric name": (
        GOOD.replace("-- metric: X", "-- metric: my metric"),
        1,
        "metric name 'my metric' is not a name (a letter, then letters, digits, '_', '.', '+' "
        "or '-'; at most 64 characters)",
    ),
    "unknown column": (
        _numerator("count(*) FILTER (WHERE nope)"),
        10,
        'the numerator does not bind over episodes: Binder Error: Referenced column "nope" '
        "not found in FROM clause!",
    ),
    "column of another table": (
        _numerator("sum(distance)"),
        10,
        'the numerator does not bind over episodes: Binder Error: Referenced column "distance" '
        "not found in FROM clause!",
    ),
    "syntax error": (
        _numerator("count(*) FILTER (WHERE"),
        10,
        'the numerator is not valid SQL: Parser Error: syntax error at or near ")"',
    ),
    "syntax error on a later line": (
        _numerator("sum(\n    CASE WHEN THEN 1 ELSE 0 END\n)"),
        11,
        'the numerator is not valid SQL: Parser Error: syntax error at or near "THEN"',
    ),
    "not an aggregate": (
        _numerator("n_goals"),
        10,
        'the numerator does not bind over episodes: Binder Error: column "n_goals" must '
        "appear in the GROUP BY clause or must be part of an aggregate function.",
    ),
    "not a number": (
        _numerator("max(model)"),
        10,
        "the numerator gives VARCHAR values, not numbers (it must be a count or a sum)",
    ),
    "two statements": (
        _numerator("count(*)); DROP VIEW steps; SELECT (1"),
        10,
        "the numerator must be one SQL expression (it holds a ';')",
    ),
    "extra columns": (
        _numerator("count(*)) AS x, (1"),
        10,
        "the numerator must be one SQL expression (it adds columns)",
    ),
    "reading a file": (
        _numerator("(SELECT count(*) FROM read_csv('/etc/passwd'))"),
        10,
        'the numerator does not bind over episodes: Permission Error: Cannot access file '
        '"/etc/passwd"',
    ),
    "a mean": (
        _numerator("avg(CAST(success AS INTEGER))"),
        10,
        "the numerator is not additive: avg(...) is not a sum or a count (the terms are added "
        "across runs, groups and resampled episodes; write a mean as a sum in the numerator "
        "over a count in the denominator)",
    ),
    "a ratio of aggregates": (
        _numerator("count(*) FILTER (WHERE success) / count(*)"),
        10,
        "the numerator is not additive: '/' applied to aggregates is not a sum of them",
    ),
    "a distinct count": (
        _numerator("count(DISTINCT episode_id)"),
        10,
        "the numerator is not additive: count(DISTINCT ...) is not a sum or a count of rows",
    ),
    "a product of aggregates": (
        _numerator("sum(n_goals) * count(*)"),
        10,
        "the numerator is not additive: '*' applied to aggregates is not a sum of them",
    ),
    "a subquery": (
        _numerator("(SELECT 1) + count(*)"),
        10,
        "the numerator is not additive: a subquery outside an aggregate is not a sum or a count",
    ),
    "denominator of another grain": (
        metric_text("X", "count(*)", "count(*) FILTER (WHERE success)", grain="steps"),
        13,
        'the denominator does not bind over steps: Binder Error: Referenced column "success" '
        "not found in FROM clause!",
    ),
}


@pytest.mark.parametrize("kind", list(MALFORMED))
def test_each_malformed_file_is_one_line_with_exit_code_1(kind, tmp_path, capsys) -> None:
    text, line, message = MALFORMED[kind]
    folder = write_folder(tmp_path / "mine", {"x.sql": text})
    code = main(["metrics", "--list", "--metrics-dir", str(folder)])
    err = capsys.readouterr().err
    assert code == 1
    assert err.count("\n") == 1, err  # one line
    assert err.startswith(f"error: {folder / 'x.sql'}:{line}: {message}"), err
    with pytest.raises(va.MetricFileError) as info:
        va.load_metrics(folder)
    assert len(info.value.problems) == 1
    assert info.value.problems[0].startswith(f"{folder / 'x.sql'}:{line}: {message}")


def test_every_problem_of_every_file_is_listed(tmp_path, capsys) -> None:
    folder = write_folder(
        tmp_path / "mine",
        {
            "a.sql": GOOD.replace("-- direction: higher", "-- directon: higher"),
            "b.sql": metric_text("B", "count(*)", "count(*)", grain="runs", unit="pct"),
            "c.sql": SR_MULTI,
            "README.md": "not a metric file: left alone",
        },
    )
    code = main(["metrics", "--list", "--metrics-dir", str(folder)])
    err = capsys.readouterr().err.splitlines()
    assert code == 1
    assert err == [
        f"error: 4 problems in the metric files of {folder}:",
        f"  {folder}/a.sql:1: missing header key direction (required: metric, title, "
        "direction, unit, grain, version, definition)",
        f"  {folder}/a.sql:3: unknown header key 'directon' (known: metric, title, direction, "
        "unit, grain, version, definition, level, null); did you mean 'direction'?",
        f"  {folder}/b.sql:4: unknown unit 'pct' (one of: percent, ratio, distance)",
        f"  {folder}/b.sql:5: unknown grain 'runs' (one of: episodes, steps, goals)",
    ]


def test_two_files_with_one_name(tmp_path, capsys, hand_out) -> None:
    folder = write_folder(tmp_path / "mine", {"a.sql": SR_MULTI, "b.sql": SR_MULTI})
    code = main(["metrics", str(hand_out), "--metrics-dir", str(folder)])
    err = capsys.readouterr().err
    assert code == 1 and err.count("\n") == 1
    assert err == (
        f"error: {folder}/b.sql:1: metric 'SR-multi' is also defined in {folder}/a.sql:1 "
        "(one file per metric)\n"
    )


def test_folder_problems(tmp_path, capsys) -> None:
    (tmp_path / "empty").mkdir()
    (tmp_path / "file.sql").write_text(GOOD)
    (tmp_path / "latin1").mkdir()
    (tmp_path / "latin1" / "x.sql").write_bytes(GOOD.replace("X\n", "X \xe9\n", 1).encode("latin-1"))
    cases = {
        tmp_path / "nowhere": "metrics folder not found",
        tmp_path / "empty": "no metric file (*.sql) in this folder",
        tmp_path / "file.sql": "not a folder (--metrics-dir takes a folder)",
    }
    for folder, message in cases.items():
        assert main(["metrics", "--list", "--metrics-dir", str(folder)]) == 1
        assert capsys.readouterr().err == f"error: {folder}: {message}\n"
    assert main(["metrics", "--list", "--metrics-dir", str(tmp_path / "latin1")]) == 1
    err = capsys.readouterr().err
    assert err.startswith(f"error: {tmp_path}/latin1/x.sql:1: not UTF-8 text")


def test_the_environment_variable_is_the_default(tmp_path, monkeypatch, capsys) -> None:
    folder = write_folder(tmp_path / "mine", {"multi.sql": SR_MULTI})
    monkeypatch.setenv("VGE_METRICS_DIR", str(folder))
    assert va.load_metrics().names[-1] == "SR-multi"
    assert main(["metrics", "--list", "-f", "csv"]) == 0
    assert f"SR-multi,Success Rate on multi-goal episodes,1,higher,percent,episodes,{folder}/" in (
        capsys.readouterr().out
    )
    monkeypatch.setenv("VGE_METRICS_DIR", "")
    assert va.load_metrics() is va.MetricSet.builtin()


def test_a_changed_file_is_read_again(tmp_path) -> None:
    folder = write_folder(tmp_path / "mine", {"multi.sql": SR_MULTI})
    first = va.load_metrics(folder)
    assert va.load_metrics(folder) is first  # kept per process
    (folder / "multi.sql").write_text(SR_MULTI.replace("-- version: 1", "-- version: 22"))
    assert va.load_metrics(folder).get("SR-multi").version == 22


def test_builtin_files_follow_the_public_format() -> None:
    # The built-ins are read by the same parser, and their SQL binds like a user's.
    base = resources.files("vge_analytics") / "sql"
    for metric in va.registry().values():
        name = metric.source.removeprefix("vge_analytics/sql/")
        parsed, problems = parse_metric_file((base / name).read_text(), metric.source)
        assert problems == [] and parsed == metric
        assert check_metric(metric) == [], metric.name


def test_additive_forms_are_accepted(tmp_path) -> None:
    # Sums and counts, combined by +, -, a constant factor, a cast or coalesce(..., 0); what
    # is inside an aggregate (a subquery in a FILTER included) is free.
    numerator = (
        "100 * count(*) FILTER (WHERE success) - coalesce(fsum(CAST(goals_completed AS DOUBLE)"
        " / n_goals), 0) + CAST(sum(n_goals) AS DOUBLE) * -0.5 + (count(*) - count(*))\n"
        "+ count(*) FILTER (WHERE (SELECT 1) = 1)"
    )
    folder = write_folder(tmp_path / "ok", {"x.sql": _numerator(numerator)})
    assert va.load_metrics(folder).get("X").numerator == numerator


def test_comments_and_continuations(tmp_path) -> None:
    text = (
        "-- A comment before the header.\n"
        "-- metric: Commented\n"
        "-- title: With comments\n"
        "-- direction: lower\n"
        "-- unit: ratio\n"
        "-- grain: steps\n"
        "-- version: 3\n"
        "-- definition: First line,\n"
        "--   second line.\n"
        "-- null: null without interactions.\n"
        "\n"
        "-- numerator\n"
        "-- a comment in the SQL\n"
        "count(*) FILTER (WHERE is_interaction AND NOT hit_component)  -- misses\n"
        "\n"
        "-- denominator\n"
        "count(*) FILTER (WHERE is_interaction)\n"
        "-- trailing comment\n"
    )
    metric, problems = parse_metric_file(text, "c.sql")
    assert problems == []
    assert metric.definition == "First line, second line."
    assert metric.numerator == (
        "count(*) FILTER (WHERE is_interaction AND NOT hit_component)  -- misses"
    )
    assert (metric.numerator_line, metric.denominator_line, metric.name_line) == (14, 17, 2)
    assert metric.level is None and metric.null_rule == "null without interactions."
    assert check_metric(metric) == []


def test_files_other_than_sql_are_left_alone(tmp_path) -> None:
    folder = write_folder(tmp_path / "mine", {"multi.sql": SR_MULTI, "notes.txt": "x"})
    (folder / "sub").mkdir()
    (folder / "sub" / "other.sql").write_text("not read: subfolders are not metric files")
    assert va.load_metrics(folder).names == (
        *va.METRIC_NAMES, *va.CONTINUATION_METRICS, "SR-multi",
    )  # fmt: skip


def test_names_in_the_path(tmp_path: Path) -> None:
    # Messages name the file as the folder was given (relative stays relative).
    folder = write_folder(tmp_path / "mine", {"x.sql": GOOD.replace("1\n", "0\n", 1)})
    with pytest.raises(va.MetricFileError, match=r"mine/x\.sql:6: version '0'"):
        va.load_metrics(folder)
