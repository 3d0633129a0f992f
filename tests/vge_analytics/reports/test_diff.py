"""`vge diff`: hand-worked pairs of trajectories, and the bundled sample against an
independent query.

Hand-worked runs A and B (`hand_pair`, built by `diff_pair.py`): copies of the kettle_c task (tests/data/hand_worked/
kettle_c_parse_multigoal_chain.json, λ 2, budget 8 steps). Its full log (8 steps) leaves,
step by step (state_after, view right throughout): 0 Standby (Click: action_error),
1 LidOpen, 2 LidOpen (two actions: action_error), 3 LidOpen (no action: action_error),
4 LidOpen (x 1200: invalid_coord), 5 Standby, 6 Boiling, 7 Standby (BoilingComplete, then the
immediate chain: success). The optimal log (4 steps, no error): lid push[1] -> LidOpen, lid
push[0] -> Standby, power push[1] -> Boiling, wait -> Standby (success).

  episode     A                 B                               steps  success  first error  first
                                                                 A  B   A  B     A  B         difference
  same        full              full                            8  8   T  T     0  0         none
  prefix      full              full[:2] (log ends)             8  2   T  F     0  0         2 (B's length)
  longer      full[:5]          full                            5  8   F  T     0  0         5 (A's length)
  view        full              full[:2] + Switch_view(front)   8  3   T  F     0  0         2 (view front)
  clean       full              optimal                         8  4   T  T     0  none      0 (LidOpen)
  swapped     full              full, steps 2 and 4 swapped     8  8   T  T     0  0         none
  late        optimal           lid push[1], x 1200, then the   4  5   T  T     none 1       1 (LidOpen
                                optimal rest                                                    vs Standby)

`swapped` differs only in the error types of steps 2 and 4 (invalid_coord and action_error
change places; both leave LidOpen in view right): errors are not differences. B also played
`only-b`, which A did not; run C played only `only-c`.

Summary by hand: (success_a, success_b): (T, T) same, clean, swapped, late = 4; (T, F) prefix,
view = 2; (F, T) longer = 1; (F, F) 0. First differences 2, 5, 2, 0, 1: median 2; identical 2
of 7. Error type at the first error: A action_error 6 (all but late), none 1; B action_error 5,
invalid_coord 1 (late), none 1 (clean).
"""

from __future__ import annotations

import json
from pathlib import Path

import polars as pl
import pytest

import vge_analytics as va
from vge_analytics.cli import main
from vge_analytics.reports import NO_ERROR

from .diff_pair import build_hand_pair

COLUMNS = [
    "episode_id",
    *(f"{name}_{run}" for name in ("steps", "success", "first_error") for run in "ab"),
    "first_difference",
]
EXPECTED = {
    "clean": (8, 4, True, True, 0, None, 0),
    "late": (4, 5, True, True, None, 1, 1),
    "longer": (5, 8, False, True, 0, 0, 5),
    "prefix": (8, 2, True, False, 0, 0, 2),
    "same": (8, 8, True, True, 0, 0, None),
    "swapped": (8, 8, True, True, 0, 0, None),
    "view": (8, 3, True, False, 0, 0, 2),
}


@pytest.fixture(scope="module")
def hand_pair(tmp_path_factory) -> Path:
    return build_hand_pair(tmp_path_factory.mktemp("diff"))


def test_the_hand_worked_steps_are_what_the_docstring_says(hand_pair: Path) -> None:
    # The premises of the derivation: the replayed states of the full log, and the error
    # types of `swapped` trading places.
    steps = va.steps(hand_pair, where={"run_id": "A", "episode_id": "same"})
    assert steps["state_after"].to_list() == [
        "Standby",
        "LidOpen",
        "LidOpen",
        "LidOpen",
        "LidOpen",
        "Standby",
        "Boiling",
        "Standby",
    ]
    swapped = va.steps(hand_pair, where={"run_id": "B", "episode_id": "swapped"})
    assert swapped["error_type"].to_list()[:5] == [
        "action_error",
        None,
        "invalid_coord",
        "action_error",
        "action_error",
    ]
    assert steps["error_type"].to_list()[2:5] == ["action_error", "action_error", "invalid_coord"]


def test_hand_worked_rows(hand_pair: Path) -> None:
    d = va.diff(hand_pair, "A", "B")
    assert d.episodes.columns == COLUMNS
    got = {row[0]: row[1:] for row in d.episodes.iter_rows()}
    assert got == EXPECTED  # only-b (B only) and only-c (C only) are left out
    assert d.episodes["episode_id"].to_list() == sorted(EXPECTED)


def test_hand_worked_summary(hand_pair: Path) -> None:
    d = va.diff(hand_pair, "A", "B")
    assert d.outcomes().rows() == [
        (True, True, 4),
        (True, False, 2),
        (False, True, 1),
        (False, False, 0),
    ]
    assert d.differences().row(0, named=True) == {
        "episodes": 7,
        "identical": 2,
        "differing": 5,
        "median_first_difference": 2.0,
    }
    assert d.first_errors().select("error_type", "episodes_a", "episodes_b").rows() == [
        ("invalid_coord", 0, 1),
        ("action_error", 6, 5),
        (NO_ERROR, 1, 1),
    ]


def test_swapping_the_runs_swaps_the_columns(hand_pair: Path) -> None:
    ab = va.diff(hand_pair, "A", "B").episodes
    ba = va.diff(hand_pair, "B", "A").episodes
    swap = {"steps_a": "steps_b", "success_a": "success_b", "first_error_a": "first_error_b"}
    swap |= {v: k for k, v in swap.items()}
    assert ba.rename(swap).select(COLUMNS).equals(ab)


def test_a_run_against_itself_is_identical_everywhere(hand_pair: Path) -> None:
    d = va.diff(hand_pair, "B", "B")
    assert d.episodes.height == 8 and d.episodes["first_difference"].null_count() == 8
    assert d.episodes["first_error_a"].to_list() == d.episodes["first_error_b"].to_list()
    assert d.differences()["median_first_difference"].to_list() == [None]


def test_chosen_episodes(hand_pair: Path) -> None:
    d = va.diff(hand_pair, "A", "B", episodes=["late", "prefix", "late"])
    assert [r[0] for r in d.episodes.iter_rows()] == ["late", "prefix"]
    assert d.differences()["median_first_difference"].to_list() == [1.5]  # (1 + 2) / 2


def test_errors(hand_pair: Path) -> None:
    with pytest.raises(va.UnknownRunError, match="unknown run 'Z'.*runs: A, B, C"):
        va.diff(hand_pair, "A", "Z")
    with pytest.raises(va.CommonEpisodesError, match="runs 'A' and 'C' have no episode in common"):
        va.diff(hand_pair, "A", "C")
    with pytest.raises(
        va.CommonEpisodesError, match="not replayed in both 'A' and 'B': episode 'nope', 'only-b'"
    ):
        va.diff(hand_pair, "A", "B", episodes=["same", "only-b", "nope"])


# ---------------------------------------------------------------------------- the command


def run(capsys, *args: str) -> tuple[int, str, str]:
    code = main(["diff", *args])
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def test_json_is_the_rows_alone(capsys, hand_pair: Path) -> None:
    code, out, _ = run(capsys, str(hand_pair), "A", "B", "--format", "json")
    assert code == 0
    rows = json.loads(out)
    assert [list(r) for r in rows] == [COLUMNS] * 7
    assert {r["episode_id"]: tuple(r.values())[1:] for r in rows} == EXPECTED


def test_csv_table_and_markdown_end_with_the_summary(capsys, hand_pair: Path) -> None:
    code, out, _ = run(capsys, str(hand_pair), "A", "B", "-f", "csv", "--episodes", "late,view")
    assert code == 0
    assert out.split("\n\n")[:4] == [
        "# A = A, B = B: 2 common episodes\n" + ",".join(COLUMNS) + "\n"
        "late,4,5,true,true,,1,1\nview,8,3,true,false,0,0,2",
        "# episodes by (success_a, success_b)\nsuccess_a,success_b,episodes\n"
        "true,true,1\ntrue,false,1\nfalse,true,0\nfalse,false,0",
        "# first difference (step, from 0)\nepisodes,identical,differing,median_first_difference\n"
        "2,0,2,1.5",
        "# error type at each run's first error (episodes)\nerror_type,label,episodes_a,episodes_b\n"
        "invalid_coord,Invalid Coord Error,0,1\naction_error,Action Error,1,1\n"
        "(no error),(no error),1,0",
    ]
    code, out, _ = run(capsys, str(hand_pair), "A", "B", "-f", "markdown")
    assert code == 0
    headings = [line for line in out.splitlines() if line.startswith("### ")]
    assert headings == [
        "### A = A, B = B: 7 common episodes",
        "### episodes by (success_a, success_b)",
        "### first difference (step, from 0)",
        "### error type at each run's first error (episodes)",
    ]
    assert "| same | 8 | 8 | true | true | 0 | 0 | – |" in out
    code, out, _ = run(capsys, str(hand_pair), "A", "B")
    assert code == 0
    assert out.index("7 common episodes") < out.index("median_first_difference")
    assert "Invalid Coord Error" in out


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["A", "Z"], "unknown run 'Z' in "),
        (["A", "C"], "runs 'A' and 'C' have no episode in common"),
        (["A", "B", "--episodes", "only-b"], "not replayed in both 'A' and 'B': episode 'only-b'"),
        (["A", "B", "--episodes", ","], "--episodes: no episode id given"),
        (
            ["A", "B", "-f", "latex"],
            "unknown format 'latex'; choose one of table, json, csv, markdown",
        ),
    ],
)
def test_command_errors_are_one_line(capsys, hand_pair: Path, args, message) -> None:
    code, out, err = run(capsys, str(hand_pair), *args)
    assert code == 1 and out == ""
    assert len(err.strip().splitlines()) == 1 and message in err


# ------------------------------------------------------------------------ bundled sample

INDEPENDENT = """
WITH paths AS (
    -- each run's scored steps as one list per episode, in step order
    SELECT run_id, episode_id,
        list({'state': state_after, 'view': view_after} ORDER BY step) AS path,
        list(error_type ORDER BY step) AS errors
    FROM steps
    WHERE NOT truncated AND run_id IN ('sim-human', 'sim-vlm-f')
    GROUP BY run_id, episode_id
),
played AS (
    SELECT e.run_id, e.episode_id, e.success,
        coalesce(p.path, []) AS path, coalesce(p.errors, []) AS errors
    FROM episodes AS e
    LEFT JOIN paths AS p ON p.run_id = e.run_id AND p.episode_id = e.episode_id
)
SELECT a.episode_id,
    len(a.path) AS steps_a,
    len(b.path) AS steps_b,
    a.success AS success_a,
    b.success AS success_b,
    list_position(list_transform(a.errors, lambda t: t IS NOT NULL), true) - 1 AS first_error_a,
    list_position(list_transform(b.errors, lambda t: t IS NOT NULL), true) - 1 AS first_error_b,
    list_position(
        list_transform(
            range(greatest(len(a.path), len(b.path))),
            lambda i: a.path[i + 1] IS DISTINCT FROM b.path[i + 1]
        ),
        true
    ) - 1 AS first_difference,
    list_filter(a.errors, lambda t: t IS NOT NULL)[1] AS type_a,
    list_filter(b.errors, lambda t: t IS NOT NULL)[1] AS type_b
FROM played AS a
JOIN played AS b ON a.episode_id = b.episode_id
WHERE a.run_id = 'sim-human' AND b.run_id = 'sim-vlm-f'
ORDER BY a.episode_id
"""


def test_the_sample_agrees_with_an_independent_query(sample_out: Path) -> None:
    """For every common episode of sim-human and sim-vlm-f, the diff equals what one query
    over the steps table computes another way: each run's states and views as a list per
    episode, compared position by position (missing positions differ), the first error
    the first non-null error type of that list (success from the episodes table)."""
    want = va.sql(sample_out, INDEPENDENT)
    d = va.diff(sample_out, "sim-human", "sim-vlm-f")
    assert want.height == d.episodes.height == 166
    got = d.episodes.with_columns(
        pl.col(c).cast(pl.Int64) for c in COLUMNS[1:] if "success" not in c
    )
    expected = want.select(COLUMNS).with_columns(
        pl.col(c).cast(pl.Int64) for c in COLUMNS[1:] if "success" not in c
    )
    assert got.equals(expected)
    # Not a vacuous agreement: the sample has every kind of row.
    assert got["first_difference"].null_count() > 0 and got["first_difference"].max() > 0
    assert got["first_error_a"].null_count() > 0 and got["first_error_b"].null_count() > 0
    assert (got["steps_a"] != got["steps_b"]).any()
    # The summary from the independent rows.
    outcomes = want.group_by("success_a", "success_b").len()
    for row in d.outcomes().iter_rows(named=True):
        n = outcomes.filter(
            (pl.col("success_a") == row["success_a"]) & (pl.col("success_b") == row["success_b"])
        )["len"]
        assert row["episodes"] == (n[0] if n.len() else 0)
    assert d.differences()["median_first_difference"][0] == want["first_difference"].median()
    types = d.first_errors()
    for side in ("a", "b"):
        counts = want[f"type_{side}"].fill_null(NO_ERROR).value_counts()
        expected_counts = dict(counts.iter_rows())
        assert dict(zip(types["error_type"], types[f"episodes_{side}"], strict=True)) == {
            t: expected_counts.get(t, 0) for t in types["error_type"]
        }
        assert sum(types[f"episodes_{side}"]) == 166
