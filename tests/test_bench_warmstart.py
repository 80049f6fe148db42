"""benchmarks/bench_warmstart.py: both starts simulated for a food, and the summary's
ratios and counts from known rows."""

from __future__ import annotations

import pytest

from benchmarks.bench_warmstart import _both_starts, summary
from benchmarks.validate_estimators import foods_of


def test_a_food_is_simulated_with_both_starts() -> None:
    """The default ``env`` probes at the 5 ms step: both starts run, each counts its Newton
    iterations, and the controller's own step is put back."""
    import mujoco

    import fetch_env.controller as controller

    row = _both_starts(foods_of("reporting", 64)[0], "env")
    assert row["cpu_previous"] > 0 and row["cpu_alternating"] > 0
    assert row["iterations_previous"] > 100 and row["iterations_alternating"] > 100
    assert controller.mujoco.mj_step is mujoco.mj_step


def test_summary_counts_and_ratios() -> None:
    rows = [{"index": 0, "cpu_previous": 4.0, "cpu_alternating": 2.0,
             "iterations_previous": 100, "iterations_alternating": 50},
            {"index": 1, "cpu_previous": 12.0, "cpu_alternating": 12.0,
             "iterations_previous": 300, "iterations_alternating": 300}]
    s = summary(rows, bar=10.0)
    assert s["previous"]["over_bar"] == 1 and s["previous"]["slowest_food"] == 1
    assert s["alternating"]["max_s"] == 12.0
    assert s["ratio_of_sums"] == pytest.approx(14.0 / 16.0)
    assert s["median_ratio"] == pytest.approx(0.75)
    assert s["iteration_ratio"] == pytest.approx(350 / 400)
    assert s["foods_with_equal_iterations"] == 1
