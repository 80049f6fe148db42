"""benchmarks/probe_twins.py: the spread over placements and the within-food share of the
error variance, on log-errors whose split into bias and chaos is known."""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
from numpy.testing import assert_allclose

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))

from probe_twins import log_errors, summary_of  # noqa: E402


def test_a_bias_repeated_by_every_placement_is_no_chaos() -> None:
    bias = np.array([0.01, -0.02, 0.05, 0.0])
    out = summary_of(np.tile(bias, (4, 1)))
    assert out["within_share"] == 0.0
    assert out["spread"]["median"] == 0.0
    assert_allclose(out["as_placed"]["median"], 0.015, rtol=1e-12)  # |0.01|, |-0.02|
    assert_allclose(out["mean"]["median"], out["as_placed"]["median"], rtol=1e-12)


def test_pure_chaos_lies_within_foods_and_averages_down() -> None:
    rng = np.random.default_rng(0)
    errors = 0.02 * rng.standard_normal((4, 4000))  # no food-to-food bias at all
    out = summary_of(errors)
    assert_allclose(out["within_share"], 1.0, atol=0.03)
    # the mean of 4 placements halves a random miss
    assert_allclose(out["mean"]["median"] / out["as_placed"]["median"], 0.5, rtol=0.05)
    # a standard deviation of 4 draws of sd 0.02: median about 0.0188
    assert_allclose(out["spread"]["median"], 0.0188, rtol=0.05)


def test_log_errors_keep_only_foods_every_placement_measured() -> None:
    truth = {"g1": 0.4}

    def rec(ratio: float) -> dict[str, dict[str, float]]:
        return {"truth": truth, "estimate": {"g1": 0.4 * ratio}}

    held = {"as placed": {0: rec(1.1), 1: rec(1.0), 2: rec(1.0)},
            "gap +1 um": {0: rec(1.1), 1: {"crash": "x"}, 2: rec(math.nan)}}
    out = log_errors(held, "g1")
    assert out.shape == (2, 1)
    assert_allclose(out[:, 0], math.log(1.1), rtol=1e-12)
