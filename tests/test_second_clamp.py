"""benchmarks/second_clamp.py: the combined estimate and the spread flag, on held-out records
whose errors are known."""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path

import pytest
from numpy.testing import assert_allclose

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))

from second_clamp import combination, table  # noqa: E402

# food -> (g1 error, tau1 error) of each clamp, as ratios estimate / truth
ERRORS = {
    0: ((1.00, 1.01), (1.00, 1.01)),  # both clamps within 1 %, agreeing: good, spread 0
    1: ((1.10, 1.00), (1.10, 1.00)),  # a 10 % miss both clamps share: bad, spread 0
    2: ((1.00, 1.00), (1.02, 1.02)),  # within 1 % on the mean, spread log 1.02: good
    3: ((1.08, 1.00), (1.00, 1.00)),  # a 4 % mean, unclassified
}


def _held() -> dict[str, dict[int, dict]]:
    truth = {"g1": 0.4, "tau1": 2.0}
    return {clamp: {i: {"truth": truth,
                        "estimate": {t: truth[t] * e[c][j] for j, t in enumerate(truth)}}
                    for i, e in ERRORS.items()}
            for c, clamp in enumerate(("a", "b"))}


def test_one_clamp_reports_its_own_errors() -> None:
    out = combination(_held(), ("a",), list(ERRORS))
    assert out["foods"] == 4
    assert "flag" not in out
    g1 = [0.0, 0.0, math.log(1.08), math.log(1.10)]  # clamp a's log errors, sorted
    assert_allclose(out["g1"]["median"], (g1[1] + g1[2]) / 2, rtol=1e-12)
    assert_allclose(out["g1"]["p95"], g1[2] + 0.85 * (g1[3] - g1[2]), rtol=1e-12)
    assert out["tau1"]["median"] == 0.0  # one food of four off, by 1 %


def test_mean_of_clamps_and_the_spread_flag() -> None:
    out = combination(_held(), ("a", "b"), list(ERRORS))
    # mean log errors of g1: 0, log 1.1, log(1.02)/2, log(1.08)/2
    g1 = sorted([0.0, math.log(1.10), math.log(1.02) / 2, math.log(1.08) / 2])
    assert out["g1"]["median"] == pytest.approx((g1[1] + g1[2]) / 2)
    # the one 5 % miss has spread 0, so no threshold passes a good food
    assert out["flag"] == {"n_over_5pct": 1, "n_under_2pct": 2, "under_2pct_passed": 0,
                           "spread_threshold": 0.0}


def test_flag_passes_good_foods_below_every_miss_spread() -> None:
    held = _held()
    held["b"][1]["estimate"]["g1"] = 0.4 * 1.20  # the miss now disagrees: spread log(1.2/1.1)
    out = combination(held, ("a", "b"), list(ERRORS))
    assert out["flag"]["under_2pct_passed"] == 2
    assert out["flag"]["spread_threshold"] == pytest.approx(math.log(1.2 / 1.1))
    assert "| a + b |" in table([out])


def test_a_failed_clamp_drops_the_food() -> None:
    held = _held()
    held["b"][2]["estimate"]["tau1"] = math.nan
    assert combination(held, ("a", "b"), list(ERRORS))["foods"] == 3


def test_committed_run_matches_the_docs() -> None:
    data = json.loads((ROOT / "docs" / "data" / "validation" / "second_clamp.json").read_text())
    page = (ROOT / "docs" / "estimator_validation.md").read_text()
    assert table(data["results"]) in page
