"""The error model's hinge on the clamps' spread and its own reliability rule
(estimators.calibration.ErrorModel.reliable_half_width and reliable_diagnostics,
fetch_env.probes.ProbeOutcome.reliable): a food's g1 and tau1 errors stay small while its
repeated clamps agree within a few per cent and grow fast past that, and the precise probes'
repeats single out the foods they miss."""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import numpy as np
import pytest

from benchmarks.validate_estimators import RELIABILITY, cross_validate, error_coverage
from estimators import calibration
from estimators.calibration import (
    ERROR_INPUTS,
    OPTIONAL_ERROR_INPUTS,
    ErrorModel,
    allowed_error_inputs,
    error_inputs,
    fit_error_model,
)
from estimators.errors import EstimationError
from estimators.uncertainty import DRIFT_DIAGNOSTICS
from fetch_env.errors import SimulationDivergedError
from fetch_env.layouts import single_block
from fetch_env.materials import Material
from fetch_env.probes import (
    PROBE_CALIBRATIONS,
    PROBE_PRESETS,
    RELIABLE_HALF_WIDTH,
    ProbeOutcome,
    apply_calibration,
    reads_drift,
    slip,
)
from tests.test_error_model import ESTIMATE, _diagnostics

DATA = Path(__file__).resolve().parents[1] / "docs" / "data" / "validation"
HINGE = {"g1": "log_repeat_sd_log_g1>0.03", "tau1": "log_repeat_sd_log_tau1>0.03"}


def test_a_hinge_input_is_how_far_the_log_is_past_its_knee() -> None:
    for spread, want in ((0.06, math.log(2.0)), (0.03, 0.0), (0.01, 0.0), (0.3, math.log(10))):
        diag = {"repeat_sd_log_tau1": spread}
        assert calibration._diagnostic_value(HINGE["tau1"], diag, "t") == pytest.approx(
            want, abs=1e-12)
    # the log's own clip (1e-3 .. 1e3) holds inside the hinge
    assert calibration._diagnostic_value("log_repeat_sd_log_g1>0.03",
                                         {"repeat_sd_log_g1": 1e6}, "t") == pytest.approx(
        math.log(1e3 / 0.03))
    with pytest.raises(EstimationError, match="repeat_sd_log_g1"):
        calibration._diagnostic_value(HINGE["g1"], {}, "t")


def test_models_fitted_before_the_hinge_still_load() -> None:
    """The input lists allowed are the base and the base plus each leading part of the
    optional inputs; a list that skips one is refused by name."""
    base = ERROR_INPUTS["tau1"]
    assert allowed_error_inputs("tau1") == (
        base, base + OPTIONAL_ERROR_INPUTS["tau1"][:1], base + OPTIONAL_ERROR_INPUTS["tau1"])
    assert OPTIONAL_ERROR_INPUTS["tau1"][-1] == HINGE["tau1"]
    with pytest.raises(EstimationError, match="inputs"):
        error_inputs("tau1", "cube", 0.015, ESTIMATE, {}, (*base, HINGE["tau1"]))


def _rows_with_spread(n: int, seed: int) -> list[tuple]:
    """Foods whose tau1 and g1 errors are ~0.3 % while their clamps' spread is under 3 % and
    ~half the spread above it."""
    rng = np.random.default_rng(seed)
    rows = []
    for _ in range(n):
        diag = _diagnostics(rng)
        resid = {}
        for k in ("g1", "tau1"):
            spread = float(math.exp(rng.uniform(math.log(2e-3), math.log(0.3))))
            diag[f"repeat_sd_log_{k}"] = spread
            resid[k] = float(rng.laplace(0.0, 0.003 if spread < 0.03 else 0.5 * spread))
        resid["mu"] = float(rng.laplace(0.0, 0.01))
        rows.append(("cube", 0.015, ESTIMATE, diag, resid))
    return rows


def test_the_hinge_narrows_the_calm_foods_intervals(monkeypatch: pytest.MonkeyPatch) -> None:
    """On foods whose error jumps past a 3 % spread, the model with the hinge covers 92-99 %
    of new foods and gives those with a spread of 1-3 %, just short of the jump, intervals
    under three quarters as wide as a model with the log spread alone, which must bend its
    one slope to the jump (measured: medians 0.0174 / 0.0253 at 1-2 %, 0.0228 / 0.0433 at
    2-3 %)."""
    train, test = _rows_with_spread(600, 21), _rows_with_spread(2000, 22)
    model = fit_error_model(train)
    assert model.input_names("tau1")[-1] == HINGE["tau1"]
    hw = np.array([model.half_width("tau1", *row[:4]) for row in test])
    err = np.array([abs(row[4]["tau1"]) for row in test])
    assert 0.92 <= np.mean(err <= hw) <= 0.99
    monkeypatch.setitem(OPTIONAL_ERROR_INPUTS, "tau1", OPTIONAL_ERROR_INPUTS["tau1"][:1])
    plain = fit_error_model(train)
    assert plain.input_names("tau1")[-1] == "log_repeat_sd_log_tau1"
    hw_plain = np.array([plain.half_width("tau1", *row[:4]) for row in test])
    spread = np.array([row[3]["repeat_sd_log_tau1"] for row in test])
    near = (spread >= 0.01) & (spread < 0.03)
    assert np.median(hw[near]) < 0.75 * np.median(hw_plain[near])


def test_an_error_model_carries_its_reliability_rule_through_its_file() -> None:
    model = fit_error_model(_rows_with_spread(200, 3), reliable_half_width={"g1": 0.05},
                            reliable_diagnostics={"repeat_sd_log_g1": 0.03})
    back = ErrorModel.from_dict(json.loads(json.dumps(model.to_dict())))
    assert back == model and back.reliable_half_width == {"g1": 0.05}
    assert back.reliable_diagnostics == {"repeat_sd_log_g1": 0.03}
    plain = fit_error_model(_rows_with_spread(200, 3)).to_dict()
    assert "reliable_half_width" not in plain and "reliable_diagnostics" not in plain


@pytest.mark.parametrize("widths", [{"K1": 0.05}, {"g1": 0.0}, {"mu": 1.0}, {"tau1": math.nan},
                                    {"g1": "0.05"}, {"g1": True}])
def test_bad_reliable_widths_are_refused_by_name_before_any_fit(widths: dict) -> None:
    with pytest.raises(EstimationError, match="reliable_half_width"):
        fit_error_model([], reliable_half_width=widths)  # no rows: refused before the fit
    model = PROBE_CALIBRATIONS["precise"].error_model
    with pytest.raises(EstimationError, match="reliable_half_width"):
        ErrorModel.from_dict(dict(model.to_dict(), reliable_half_width=widths))


@pytest.mark.parametrize("limits", [{"": 0.1}, {"rho": 0.0}, {"rho": -1.0}, {"rho": math.inf},
                                    {"rho": "0.1"}, {"rho": True}, {3: 0.1}])
def test_bad_diagnostic_limits_are_refused_by_name_before_any_fit(limits: dict) -> None:
    with pytest.raises(EstimationError, match="reliable_diagnostics"):
        fit_error_model([], reliable_diagnostics=limits)
    model = PROBE_CALIBRATIONS["precise"].error_model
    with pytest.raises(EstimationError, match="reliable_diagnostics"):
        ErrorModel.from_dict(dict(model.to_dict(), reliable_diagnostics=limits))


def _outcome(half: dict[str, float], widths: dict[str, float] | None,
             limits: dict[str, float] | None = None,
             diagnostics: dict[str, float] | None = None) -> ProbeOutcome:
    details: dict = {} if widths is None else {"reliable_half_width": widths}
    if limits is not None:
        details["reliable_diagnostics"] = limits
    details["diagnostics"] = diagnostics or {}
    return ProbeOutcome(estimates=dict(ESTIMATE), visco_valid=True, friction_valid=True,
                        wall_time=0.0, piece_index=0, details=details,
                        intervals={k: (v * (1 - half.get(k, 0.01)), v * (1 + half.get(k, 0.01)))
                                   for k, v in ESTIMATE.items()})


def test_the_reliable_flag_reads_the_model_widths_else_the_default() -> None:
    wide_g1_mu = {"g1": 0.04, "tau1": 0.02, "mu": 0.045}
    assert RELIABLE_HALF_WIDTH == 0.025
    assert not _outcome(wide_g1_mu, None).reliable
    assert _outcome(wide_g1_mu, {"g1": 0.05, "mu": 0.05}).reliable
    assert not _outcome(dict(wide_g1_mu, tau1=0.03), {"g1": 0.05, "mu": 0.05}).reliable
    assert not _outcome(dict(wide_g1_mu, g1=0.051), {"g1": 0.05, "mu": 0.05}).reliable


def test_the_reliable_flag_reads_the_diagnostic_limits_by_absolute_value() -> None:
    limits = {"repeat_sd_log_tau1": 0.06, "drift_log_tau1": 0.1}
    calm = {"repeat_sd_log_tau1": 0.059, "drift_log_tau1": -0.099}
    assert _outcome({}, None, limits, calm).reliable
    for name, v in (("repeat_sd_log_tau1", 0.061), ("drift_log_tau1", -0.101),
                    ("drift_log_tau1", math.nan)):
        out = _outcome({}, None, limits, dict(calm, **{name: v}))
        assert not out.reliable and out.diagnostics_past_limits() == [f"{name}={v:.3g}"]
    missing = _outcome({}, None, limits, {"repeat_sd_log_tau1": 0.01})
    assert not missing.reliable
    assert missing.diagnostics_past_limits() == ["drift_log_tau1 missing"]
    odd = _outcome({}, None, limits, dict(calm, drift_log_tau1=None))
    assert odd.diagnostics_past_limits() == ["drift_log_tau1=nan"]
    assert _outcome({}, None, None, {"drift_log_tau1": 5.0}).reliable  # no limits: widths only


def test_a_limit_on_a_diagnostic_no_food_has_is_refused() -> None:
    """A misspelt name would flag every food unreliable: refused at the fit, by name."""
    with pytest.raises(EstimationError, match=r"'repeat_sd_log_tua1'.*none of the 200"):
        fit_error_model(_rows_with_spread(200, 3),
                        reliable_diagnostics={"repeat_sd_log_tua1": 0.06})


def test_the_drift_fit_runs_where_a_reliability_limit_reads_it() -> None:
    """The drift diagnostics cost a fit per clamp: run where the calibration's features or
    its error model's limits read them, or with no calibration, and only there."""
    precise = PROBE_CALIBRATIONS["precise"]
    assert reads_drift(None) and reads_drift(precise)
    features_only = dataclasses.replace(precise, error_model=dataclasses.replace(
        precise.error_model, reliable_diagnostics={}))
    assert reads_drift(features_only) == (
        not set(DRIFT_DIAGNOSTICS).isdisjoint(precise.feature_names))
    no_drift = PROBE_CALIBRATIONS["measure"]
    assert set(DRIFT_DIAGNOSTICS).isdisjoint(no_drift.feature_names) == (
        not reads_drift(no_drift))
    limited = dataclasses.replace(no_drift, error_model=dataclasses.replace(
        no_drift.error_model, reliable_diagnostics={"drift_log_tau1": 0.1}))
    assert reads_drift(limited)


def test_slides_that_could_not_all_be_compared_give_no_agreement_to_read() -> None:
    """Where one of the precise probes' five slides gives no mu, the others' spread
    would say they agree when that one could not be compared: ``mu_trials`` is left out,
    so the precise error model gives mu no interval and its limits call the food
    unreliable."""
    material = Material(young=8e5, g1=0.35, tau1=1.2, mu=0.4)
    piece = dataclasses.replace(single_block("ellipsoid", 0.012, material)[0], x=0.0, y=0.0)
    config = PROBE_PRESETS["precise"]
    slides = [slip._slide_run(piece, config, None, t) for t in slip.slide_times(config)]
    lost = SimulationDivergedError("diverged", {}, {})
    outs = []
    for ahead in (slides, [slides[0], lost, *slides[2:]]):
        out = ProbeOutcome(estimates=dict(ESTIMATE), visco_valid=True, friction_valid=False,
                           wall_time=0.0, piece_index=0,
                           details={"diagnostics": dict(_diagnostics(np.random.default_rng(1)),
                                                        repeat_sd_log_g1=0.01,
                                                        repeat_sd_log_tau1=0.01)},
                           intervals={k: (0.99 * v, 1.01 * v) for k, v in ESTIMATE.items()})
        slip._slip_probe(piece, config, None, 0.0, np.random.default_rng(0), out, False,
                           ahead=ahead)
        outs.append(out)
    whole, partial = outs
    assert whole.details["diagnostics"]["mu_trials"] >= 0.0
    assert "mu_trials" not in partial.details["diagnostics"]
    assert partial.friction_valid and partial.estimates["mu"] > 0
    assert any(f"1 of {config.slip_repeats} slides" in w for w in partial.warnings), \
        partial.warnings
    model = PROBE_CALIBRATIONS["precise"].error_model
    with pytest.raises(EstimationError, match="mu_trials"):
        model.half_width("mu", "ellipsoid", 0.012, partial.estimates,
                         partial.details["diagnostics"])
    partial.details["reliable_diagnostics"] = dict(model.reliable_diagnostics)
    assert "mu_trials missing" in partial.diagnostics_past_limits()


def test_the_precise_calibration_ships_its_rule_and_applies_it() -> None:
    cal = PROBE_CALIBRATIONS["precise"]
    rule = RELIABILITY["precise"]
    assert dict(cal.error_model.reliable_half_width) == rule["reliable_half_width"]
    assert dict(cal.error_model.reliable_diagnostics) == rule["reliable_diagnostics"]
    noisy = cal.error_model.noisy
    assert noisy is not None and noisy.n_foods >= 256  # every noisy tuning food, and more
    assert dict(noisy.reliable_half_width) == rule["noisy"]["reliable_half_width"]
    assert dict(noisy.reliable_diagnostics) == rule["noisy"]["reliable_diagnostics"]
    for k in ("g1", "tau1"):
        assert cal.error_model.input_names(k)[-1] == HINGE[k]
    assert cal.error_model.input_names("mu")[-2:] == ("log_mu_trials", "log_rms>0.003")
    records = json.loads((DATA / "tuning_precise_uncal_noise0.json").read_text())["records"]
    out = _applied("precise", records[0])
    assert out.details["reliable_half_width"] == rule["reliable_half_width"]
    assert out.details["reliable_diagnostics"] == rule["reliable_diagnostics"]
    assert out.reliable and not any("reproducibly" in w for w in out.warnings)
    assert "reliable_half_width" not in _applied("measure", records[0]).details
    scattered = next(r for r in records if r["diagnostics"]["repeat_sd_log_tau1"] > 0.2)
    out = _applied("precise", scattered)
    assert not out.reliable
    assert any("not measure this food reproducibly" in w and "repeat_sd_log_tau1=" in w
               for w in out.warnings), out.warnings


def test_a_calmer_hold_does_not_narrow_mus_interval_a_noisy_one_widens_it() -> None:
    """mu's error model reads only whether the traces carry sensor noise from the hold fit's
    residual (a hinge at rms 0.003): mu's error does not follow how calm a calm hold is (a
    log-linear term narrowed a reporting food's interval to +-2.6 % on a hold of rms e^-13,
    around a 7 % miss), while sensor noise makes mu's noise part mean a larger error.  A
    noisy hold is measured by the model's noisy model (fitted on the noisy foods alone)."""
    model = PROBE_CALIBRATIONS["precise"].error_model
    records = json.loads((DATA / "tuning_precise_uncal_noise0.json").read_text())["records"]
    rec = next(r for r in records if "crash" not in r and r["diagnostics"]["log_rms"] < -6)
    est, diag = rec.get("uncalibrated") or rec["estimate"], dict(rec["diagnostics"])

    def width(log_rms: float) -> float:
        return model.half_width("mu", rec["food"]["shape"], rec["food"]["size"], est,
                                dict(diag, log_rms=log_rms))

    calm = width(diag["log_rms"])
    assert width(-13.0) == pytest.approx(calm, rel=1e-12)
    assert width(math.log(0.003)) == pytest.approx(calm, rel=1e-12)
    assert width(math.log(0.03)) > 1.5 * calm  # measured 1.8x
    assert model.for_food(dict(diag, log_rms=math.log(0.03))) is model.noisy
    assert model.for_food(dict(diag, log_rms=-13.0)) is model


def _applied(preset: str, rec: dict) -> ProbeOutcome:
    out = ProbeOutcome(estimates=dict(rec.get("uncalibrated") or rec["estimate"]),
                       visco_valid=True,
                       friction_valid=True, wall_time=0.0, piece_index=0,
                       details={"diagnostics": rec["diagnostics"]},
                       intervals={k: tuple(v) for k, v in rec["interval"].items()})
    apply_calibration(rec["food"]["shape"], rec["food"]["size"], PROBE_CALIBRATIONS[preset], out)
    return out


def test_held_out_precise_tuning_foods_no_large_miss_is_reliable() -> None:
    """The precise calibration and its error model (with its noisy model) refitted eight
    times, each without an eighth of the 512 tuning foods (calm and with 1 % noise): on the
    held-out foods, coverage of g1, tau1 and mu stays within 90-99 %; with and without noise
    no food with a g1, tau1 or mu error over 5 % is flagged reliable (21 such foods in
    each); at most one with a mu error over 3 % is (measured: 1 of 2 without noise, a 3.1 %
    small cube, and 1 of 3 with noise, a 4.1 % miss whose five slides agree; the slides'
    limit is set on their larger study, where it flags the one reading past 5 %); at most
    8.5 % of the foods whose errors are all under 2 % are flagged unreliable without noise
    (measured: 34 of 452, 7.5 %) and at most 12 % with noise (46 of 409, 11.2 %).  Of
    those, 7 and 7 lie outside their fold's reference foods (each fold's range is drawn
    from seven eighths of the foods; on the reporting foods, against the whole tuning
    runs' range, 0 of 58 and 0 of 47 such foods do)."""
    runs = [json.loads((DATA / f"tuning_precise_uncal_noise{nz}.json").read_text())["records"]
            for nz in ("0", "0.01")]
    held = cross_validate(runs[0], runs, coverage=error_coverage("precise"),
                          reliability=RELIABILITY["precise"])
    for h in held:
        assert h["reliability"]["over_5pct_flagged_reliable"] == 0, h["reliability"]
        assert h["reliability"]["n_over_5pct"] >= 10
        for k in ("g1", "tau1", "mu"):
            assert 0.90 <= h[k]["coverage"] <= 0.99, (k, h[k]["coverage"])
        mu_off = [r for r in h["records"] if abs(r["error"]["mu"]) > 0.03]
        assert len(mu_off) >= 2, len(mu_off)
        assert sum(r["reliable"] for r in mu_off) <= 1, mu_off
    calm, noisy = held[0]["reliability"], held[1]["reliability"]
    assert calm["n_under_2pct"] >= 400 and noisy["n_under_2pct"] >= 380
    assert calm["under_2pct_flagged_unreliable"] <= 0.085 * calm["n_under_2pct"], calm
    assert noisy["under_2pct_flagged_unreliable"] <= 0.12 * noisy["n_under_2pct"], noisy
