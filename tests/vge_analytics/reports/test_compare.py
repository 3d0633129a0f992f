"""`compare` on a constructed pair with a known answer.

Pair (conftest): ten copies ep00..ep09 of the kettle_c task. A solves ep00 and ep01 (full
kettle_c log), B solves ep01..ep06; every other episode plays the first two kettle_c steps
(a parse failure, then goal 1) and the log ends. B also played ep10, which A did not.

- Common episodes: ep00..ep09 (10); ep10 is B's only.
- SR: A 2/10 = 20%, B 6/10 = 60%, B - A = 40 points.
- McNemar: b (A only) = 1 (ep00), c (B only) = 5 (ep02..ep06), n = 6;
  p = 2 * P(X <= 1 | Bin(6, 1/2)) = 2 * (1 + 6) / 64 = 14/64 = 0.21875.
- Errors: the full log has action_error x3 + invalid_coord x1, the short one action_error x1.
  A: 2 full + 8 short -> action_error 14, invalid_coord 2 (87.5%, 12.5%);
  B (common only): 6 full + 4 short -> action_error 22, invalid_coord 6 (78.57%, 21.43%);
  difference B - A: action_error -8.93 pp, invalid_coord +8.93 pp (= 600/28 - 12.5).
"""

from __future__ import annotations

import math
from pathlib import Path

import polars as pl
import pytest

import vge_analytics as va


def test_mcnemar_exact_values() -> None:
    assert va.mcnemar_exact(0, 0) == 1.0
    assert va.mcnemar_exact(1, 5) == 14 / 64
    assert va.mcnemar_exact(5, 1) == 14 / 64
    assert va.mcnemar_exact(0, 10) == 2 / 1024
    assert va.mcnemar_exact(3, 3) == 1.0  # capped at 1
    # 2 * P(X <= 2 | Bin(12, 1/2)) = 2 * (1 + 12 + 66) / 4096
    assert va.mcnemar_exact(2, 10) == 158 / 4096


def test_compare_known_answer(pair_out: Path) -> None:
    c = va.compare(pair_out, "A", "B", seed=7, resamples=500)
    assert (c.n_common, c.n_only_a, c.n_only_b) == (10, 0, 1)
    assert (c.model_a, c.model_b) == ("gemini-sim", "human-sim")
    sr = c.metrics.filter(pl.col("metric") == "SR").row(0, named=True)
    assert sr["A"] == pytest.approx(20.0) and sr["B"] == pytest.approx(60.0)
    assert sr["diff"] == pytest.approx(40.0)
    assert sr["ci_low"] <= sr["diff"] <= sr["ci_high"]
    assert sr["ci_low"] >= -100 and sr["ci_high"] <= 100
    m = c.mcnemar.row(0, named=True)
    assert (m["both"], m["a_only"], m["b_only"], m["neither"]) == (1, 1, 5, 3)
    assert m["p_value"] == 0.21875
    flips = c.flips
    assert flips.filter(pl.col("direction") == "A_only")["episode_id"].to_list() == ["ep00"]
    assert flips.filter(pl.col("direction") == "B_only")["episode_id"].to_list() == [
        "ep02",
        "ep03",
        "ep04",
        "ep05",
        "ep06",
    ]
    errors = {r["error_type"]: r for r in c.errors.iter_rows(named=True)}
    assert (errors["action_error"]["count_a"], errors["action_error"]["count_b"]) == (14, 22)
    assert (errors["invalid_coord"]["count_a"], errors["invalid_coord"]["count_b"]) == (2, 6)
    assert errors["invalid_coord"]["diff_pp"] == pytest.approx(600 / 28 - 12.5)
    assert errors["action_error"]["diff_pp"] == pytest.approx(2200 / 28 - 87.5)
    assert math.isclose(c.errors["diff_pp"].sum(), 0.0, abs_tol=1e-9)


def test_compare_is_seeded(pair_out: Path) -> None:
    a = va.compare(pair_out, "A", "B", seed=3, resamples=300).metrics
    b = va.compare(pair_out, "A", "B", seed=3, resamples=300).metrics
    assert a.equals(b)
    other = va.compare(pair_out, "A", "B", seed=4, resamples=300).metrics
    assert other["diff"].equals(a["diff"])  # point estimates do not depend on the seed


def test_compare_swapped_is_negated(pair_out: Path) -> None:
    ab = va.compare(pair_out, "A", "B", resamples=50).metrics
    ba = va.compare(pair_out, "B", "A", resamples=50).metrics
    for x, y in zip(ab["diff"].to_list(), ba["diff"].to_list(), strict=True):
        assert x == pytest.approx(-y)


def test_compare_errors(pair_out: Path, hand_out: Path) -> None:
    with pytest.raises(va.UnknownRunError, match="unknown run 'C'"):
        va.compare(pair_out, "A", "C")
    with pytest.raises(va.AnalyticsError, match="no episode in common"):
        va.compare(hand_out, "kettle-vlm", "oven-human")
    with pytest.raises(va.AnalyticsError, match="two different runs"):
        va.compare(pair_out, "A", "A")
