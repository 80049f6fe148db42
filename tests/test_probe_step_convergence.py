"""benchmarks/probe_step_convergence.py: its summary of errors per physics step and of one
food's spread over the fine steps, on records whose answers are known."""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path

import numpy as np
import pytest
from numpy.testing import assert_allclose

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))

from probe_step_convergence import _steps, summarize, table  # noqa: E402

STEPS = (0.005, 0.001, 0.0005)


def _records() -> list[dict]:
    """Three foods; tau1's error at each step is known, g1's is 1 % everywhere."""
    tau = {0: (0.10, 0.02, 0.04), 1: (0.05, 0.05, 0.05), 2: (-0.02, 0.01, -0.01)}
    return [{"index": i, "step": s, "cpu_s": 0.1 * (j + 1),
             "error": {"g1": 0.01, "tau1": tau[i][j]}}
            for i in tau for j, s in enumerate(STEPS)]


def test_summary_per_step_and_spread() -> None:
    out = summarize(_records(), STEPS)
    rows = {r["step"]: r for r in out["rows"]}
    assert_allclose(rows[0.005]["tau1"]["median_signed"], 0.05, atol=1e-12)
    assert_allclose(rows[0.005]["tau1"]["median_abs"], 0.05, atol=1e-12)
    assert_allclose(rows[0.001]["tau1"]["median_abs"], 0.02, atol=1e-12)
    assert_allclose(rows[0.0005]["cpu_s_median"], 0.3, atol=1e-12)
    assert rows[0.001]["measured"] == 3
    # the spread uses the steps of 1 ms and finer only: 0.001 and 0.0005
    sds = [np.std([math.log1p(a), math.log1p(b)], ddof=1)
           for a, b in ((0.02, 0.04), (0.05, 0.05), (0.01, -0.01))]
    assert out["spread"]["steps"] == [0.001, 0.0005]
    assert_allclose(out["spread"]["tau1"]["median"], np.median(sds), rtol=1e-12)
    assert_allclose(out["spread"]["g1"]["median"], 0.0, atol=1e-15)
    assert "| 5 ms | 3 of 3 |" in table(out)


def test_failed_foods_are_counted_not_summarized() -> None:
    recs = _records() + [{"index": 3, "step": s, "crash": "EstimationError: no contact"}
                         for s in STEPS]
    out = summarize(recs, STEPS)
    rows = {r["step"]: r for r in out["rows"]}
    assert rows[0.005]["foods"] == 4 and rows[0.005]["measured"] == 3
    assert out["spread"]["tau1"]["foods"] == 3


@pytest.mark.parametrize("text", ["0.005", "0.005,abc", "0.005,0.5", "0,0.001"])
def test_bad_steps_are_refused_naming_them(text: str) -> None:
    import argparse

    with pytest.raises(argparse.ArgumentTypeError, match="--steps"):
        _steps(text)


def test_committed_run_is_the_documented_one() -> None:
    """The committed run's table is the one docs/estimator_validation.md shows, and its
    numbers are what the page's text quotes."""
    data_dir = ROOT / "docs" / "data" / "probe_steps"
    data = json.loads((data_dir / "convergence.json").read_text())
    steps = tuple(r["step"] for r in data["summary"]["rows"])
    assert table(summarize(data["records"], steps)) == (data_dir / "convergence.md").read_text()
    page = (ROOT / "docs" / "estimator_validation.md").read_text()
    assert (data_dir / "convergence.md").read_text().strip() in page
