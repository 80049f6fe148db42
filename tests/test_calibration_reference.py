"""A calibration holds only over its reference foods: its reference range, how a food
outside it is flagged, and that the shipped ``precise`` calibration flags the stiff foods
(5-200 MPa) it was never fitted on while leaving the food space's flags as they were."""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import pytest
from numpy.testing import assert_allclose

from benchmarks.validate_estimators import held_out_record
from estimators import EstimationError
from estimators.calibration import (
    REFERENCE_QUANTITIES,
    Calibration,
    fit_calibration,
    reference_quantities,
    reference_range,
)
from fetch_env.probes import PROBE_CALIBRATIONS, ProbeOutcome, apply_calibration

DATA = Path(__file__).resolve().parents[1] / "docs" / "data" / "validation"

# A food within any calibration's reference foods: 15 mm, K_el / size 67 kN/m^2 (about 0.2 MPa)
FOOD = ("cube", 0.015, {"K1": 575.0, "K2": 425.0, "B": 1558.0, "mu": 0.3, "g1": 0.425,
                        "tau1": 3.667})
ZERO = {t: (0.0,) * 8 for t in ("K_el", "g1", "tau1")}


def _foods(n: int) -> list:
    """``n`` reference foods (shape, size, estimate, truth) spanning a known range: sizes
    10-20 mm, K_el 200-2000 N/m, g1 0.2-0.6, tau1 1-5 s, mu 0.2-0.6, estimates exact."""
    out = []
    for i in range(n):
        u = i / (n - 1)
        k_el, g1, tau1 = 200 * 10**u, 0.2 + 0.4 * u, 1 + 4 * (1 - u)
        est = {"K1": (1 - g1) * k_el, "K2": g1 * k_el, "B": tau1 * g1 * k_el, "g1": g1,
               "tau1": tau1, "mu": 0.6 - 0.4 * u}
        out.append((("cube", "ellipsoid", "sphere")[i % 3], 0.010 + 0.010 * u, est, dict(est)))
    return out


def test_a_fit_records_the_range_of_its_reference_foods() -> None:
    foods = _foods(30)
    cal = fit_calibration(foods)
    r = cal.reference_range
    assert r is not None and set(r) == set(REFERENCE_QUANTITIES)
    assert_allclose(r["size"], (0.010, 0.020), rtol=1e-12)
    assert_allclose(r["stiffness_per_size"], (200 / 0.010, 2000 / 0.020), rtol=1e-12)
    assert_allclose(r["g1"], (0.2, 0.6), rtol=1e-12)
    assert_allclose(r["tau1"], (1.0, 5.0), rtol=1e-12)
    assert_allclose(r["mu"], (0.2, 0.6), rtol=1e-12)
    assert Calibration.from_dict(cal.to_dict()) == cal
    assert reference_range([f[:3] for f in foods]) == r


def test_a_file_without_a_range_reads_as_unknown_and_saturated_fits_are_left_out() -> None:
    cal = fit_calibration(_foods(30))
    old = cal.to_dict()
    del old["reference_range"]
    assert Calibration.from_dict(old).reference_range is None
    listed = Calibration.from_dict({**cal.to_dict()})  # lists in the file, tuples in memory
    assert listed == cal and isinstance(listed.reference_range["g1"], tuple)  # type: ignore[index]
    foods = [f[:3] for f in _foods(30)]
    stuck = ("cube", 0.015, {**foods[0][2], "g1": 0.999999, "tau1": 40.0})
    assert reference_range([*foods, stuck]) == reference_range(foods)


def test_a_food_outside_the_range_is_named_and_one_inside_is_not() -> None:
    cal = fit_calibration(_foods(30))
    shape, size, est = "sphere", 0.015, dict(_foods(30)[15][2])
    assert cal.outside_reference(shape, size, est) == []
    stiff = {**est, "K1": 100 * est["K1"], "K2": 100 * est["K2"]}
    out = cal.outside_reference(shape, size, stiff)
    assert len(out) == 1 and out[0].startswith("stiffness per size") and "MN/m^2" in out[0]
    big = cal.outside_reference(shape, 0.025, {**est, "g1": 0.15})
    assert big == ["size 25 mm, 25 % above the reference foods' greatest, 20",
                   "g1 0.15, 25 % below the reference foods' least, 0.2"]
    # a calibration without a range (fitted elsewhere) knows of no outside
    assert dataclasses.replace(cal, reference_range=None).outside_reference(
        shape, size, stiff) == []


@pytest.mark.parametrize("bad", [
    {"size": (0.01, 0.02)},  # a quantity missing
    {q: (1.0, 0.5) for q in REFERENCE_QUANTITIES},  # low above high
    {q: (0.0, math.nan) for q in REFERENCE_QUANTITIES},
    "wide",
])
def test_a_bad_reference_range_is_refused(bad: object) -> None:
    with pytest.raises(EstimationError, match="reference_range"):
        Calibration(ZERO, reference_range=bad)  # type: ignore[arg-type]


def test_reference_range_needs_a_complete_food() -> None:
    with pytest.raises(EstimationError, match="at least one food"):
        reference_range([("cube", 0.01, {**FOOD[2], "tau1": math.nan})])
    with pytest.raises(EstimationError, match="shape"):
        reference_quantities("blob", 0.01, FOOD[2])


def _outcome() -> ProbeOutcome:
    half = {"g1": 0.01, "tau1": 0.01, "mu": 0.01}
    est = dict(FOOD[2])
    return ProbeOutcome(estimates=est, visco_valid=True, friction_valid=True, wall_time=0.0,
                        piece_index=0, intervals={k: (est[k] * (1 - h), est[k] * (1 + h))
                                                  for k, h in half.items()})


def test_an_outcome_outside_the_reference_foods_is_not_reliable_and_says_why() -> None:
    shape, size, _ = FOOD
    inside = Calibration(ZERO, reference_range={q: (0.0, 1e12) for q in REFERENCE_QUANTITIES})
    out = _outcome()
    apply_calibration(shape, size, inside, out)
    assert out.reliable and "outside_reference" not in out.details
    narrow = {**inside.reference_range, "stiffness_per_size": (1e3, 1e4)}  # type: ignore[dict-item]
    out = _outcome()
    apply_calibration(shape, size, dataclasses.replace(inside, reference_range=narrow), out)
    assert not out.reliable
    assert out.details["outside_reference"] == [
        "stiffness per size 0.06667 MN/m^2, 6.67 times the reference foods' greatest, 0.01"]
    assert any("outside the calibration's reference foods" in w for w in out.warnings)
    assert_allclose(out.estimates["g1"], FOOD[2]["g1"])  # still calibrated and reported


def _records(name: str) -> list[dict]:
    return [r for r in json.loads((DATA / f"{name}.json").read_text())["records"]
            if "crash" not in r]


def _worst(r: dict) -> float:
    return max(abs(r["error"][k]) for k in ("g1", "tau1", "mu"))


def test_the_precise_calibration_flags_the_stiff_foods_it_was_not_fitted_on() -> None:
    """On the committed stiff runs (5-200 MPa, seed 2001), recomputed from the probes' raw
    estimates with the shipped calibration: no food more than 5 % off is called reliable,
    most lie outside the reference foods, and those inside (under 10 MPa) are measured
    within 4 %."""
    cal = PROBE_CALIBRATIONS["precise"]
    for name in ("stiff_precise_noise0", "stiff_precise_noise0.01"):
        held = [held_out_record(r, cal) for r in _records(name)]
        misses = [h for h in held if _worst(h) > 0.05]
        assert len(misses) >= 10, name
        assert not any(h["reliable"] for h in misses), name
        outside = [h for h in held if h.get("uncalibrated") and not h["reliable"] and
                   cal.outside_reference(h["food"]["shape"], h["food"]["size"],
                                         h["uncalibrated"])]
        assert len(outside) >= 0.75 * len(held), name
        # what is left inside is identified: the softest of the stiff foods, within 4 %
        inside = [h for h in held if h.get("uncalibrated") and not cal.outside_reference(
            h["food"]["shape"], h["food"]["size"], h["uncalibrated"])]
        assert inside and max(_worst(h) for h in inside) < 0.04, name
        assert max(h["food"]["young"] for h in inside) < 10e6, name
        # the committed records are what the probes wrote with this calibration
        assert [h["reliable"] for h in held] == [r["reliable"] for r in _records(name)]


@pytest.mark.parametrize("name", ["reporting_precise_noise0", "reporting_precise_noise0.01"])
def test_the_food_space_flags_are_as_committed(name: str) -> None:
    """Within the food space the reference range changes nothing: the reporting foods'
    flags recomputed with the shipped calibration are the committed ones, and at most one
    of the 64 lies outside the tuning foods."""
    cal = PROBE_CALIBRATIONS["precise"]
    recs = _records(name)
    held = [held_out_record(r, cal) for r in recs]
    assert [h["reliable"] for h in held] == [r["reliable"] for r in recs]
    outside = [r for r in recs if cal.outside_reference(r["food"]["shape"], r["food"]["size"],
                                                        r["uncalibrated"])]
    assert len(outside) <= 1


@pytest.mark.parametrize(("key", "runs"), [
    ("precise", "tuning_precise_uncal"), ("measure", "tuning_measure_uncal"),
    ("env", "tuning_env_uncal"), ("repeated", "tuning_repeated_uncal"),
    ("measure/block-study", "block_measure_uncal")])
def test_each_shipped_range_is_that_of_its_committed_tuning_runs(key: str, runs: str) -> None:
    """The shipped ranges are what ``--fit-calibration ... --range-only`` computes from the
    runs each calibration names (no g1 at its fit's bound among them)."""
    from benchmarks.validate_estimators import runs_reference_range

    shipped = PROBE_CALIBRATIONS[key].reference_range
    assert shipped == runs_reference_range([_records(f"{runs}_noise{nz}")
                                            for nz in ("0", "0.01")])
    assert shipped is not None and shipped["g1"][1] < 0.99


def test_range_only_is_refused_with_cross_validation_or_a_form() -> None:
    from benchmarks.validate_estimators import main

    for extra in (["--cross-validate"], ["--form", "quadratic"], []):
        args = ["--range-only", *extra] + (
            ["--fit-calibration", str(DATA / "tuning_precise_uncal_noise0.json")]
            if extra else [])
        with pytest.raises(SystemExit) as stop:
            main(args)
        assert stop.value.code == 2, args


def test_a_resumed_run_counts_its_earlier_sittings(tmp_path: Path) -> None:
    from benchmarks.validate_estimators import _earlier_wall_s

    summary = tmp_path / "run.json"
    assert _earlier_wall_s(summary) == 0.0
    summary.write_text(json.dumps({"meta": {"wall_s": 10.0, "wall_s_earlier": 5.0}}))
    assert _earlier_wall_s(summary) == 15.0
