"""benchmarks/relaxation_contact.py: the per-shape summary of one relaxation clamp's errors,
on records whose errors are known, and its committed run against the claims made of it."""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Any

import pytest
from numpy.testing import assert_allclose

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))

from relaxation_contact import shape_summary, table  # noqa: E402


def record(shape: str, g1: float, tau1: float, cpu: float = 1.0, valid: bool = True
           ) -> dict[str, Any]:
    return {"food": {"shape": shape}, "visco_valid": valid, "cpu_probes": cpu,
            "error": {"g1": g1, "tau1": tau1}}


def test_the_summary_counts_each_shape_and_its_identified_foods() -> None:
    recs = [record("cube", 0.01 * i, -0.02 * i, cpu=i) for i in range(1, 11)]
    recs += [record("cube", 0.5, 0.5, valid=False), {"food": {"shape": "cube"}, "crash": "x"},
             record("sphere", 0.001, 0.002)]
    s = shape_summary(recs, "cube")
    assert (s["foods"], s["identified"]) == (12, 10)
    assert_allclose([s["g1"]["median"], s["g1"]["max"]], [0.055, 0.10], rtol=1e-12)
    assert_allclose([s["tau1"]["median"], s["tau1"]["p90"]], [0.11, 0.182], rtol=1e-12)
    assert s["cpu_probes_median"] == pytest.approx(5.5)
    assert shape_summary(recs, "ellipsoid")["g1"] is None
    text = table({"precise": {"cube": s}})
    row = "| precise | cube | 10 of 12 | 5.50 / 9.1 / 10 % | 11.00 / 18.2 / 20 % | 5.50 s |"
    assert row in text


def test_the_committed_run_shows_what_the_docs_claim() -> None:
    """The precise physics reads tau1 within 1 % median and g1 within 0.6 % on every shape
    of the 256 tuning foods, uncalibrated, where the measure probes read tau1 4.9-8.8 %;
    each identifies at least as many foods (docs/estimator_validation.md)."""
    data = json.loads((ROOT / "docs" / "data" / "validation" / "relaxation_contact.json")
                      .read_text())
    r = data["results"]
    assert data["meta"]["n"] == 256
    for shape in ("cube", "ellipsoid", "sphere"):
        best, base = r["precise"][shape], r["measure"][shape]
        assert best["tau1"]["median"] < 0.01 and best["g1"]["median"] < 0.006, shape
        assert base["tau1"]["median"] > 0.045, shape
        assert best["identified"] >= base["identified"], shape
