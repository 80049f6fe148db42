"""Probe calibration (estimators.calibration): a known bias model is recovered and undone."""

from __future__ import annotations

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose

from estimators import EstimationError
from estimators.calibration import (
    EXTRA_FEATURES,
    FEATURES,
    QUADRATIC_MIN_FOODS,
    Calibration,
    design,
    design_names,
    features,
    fit_calibration,
)
from fetch_env.probes import PROBE_CALIBRATIONS

TRUE_B = {
    "K_el": (0.05, -0.01, 0.02, 0.08, -0.03, 0.0, -0.04, 0.0),
    "g1": (-0.04, 0.02, 0.0, 0.03, -0.02, 0.015, 0.0, 0.0),
    "tau1": (0.08, -0.01, -0.005, 0.0, 0.02, 0.05, 0.0, -0.01),
}


# TRUE_B's linear bias plus three curved terms, over the quadratic design's columns
QUAD_NAMES = design_names(FEATURES, "quadratic")
TRUE_Q = {t: tuple(b) + tuple({("K_el", "log_stiffness*log_stiffness"): 0.012,
                               ("g1", "log_size*g1"): -0.15,
                               ("tau1", "log_tau1*log_tau1"): 0.03,
                               ("tau1", "log_stiffness*mu"): -0.02}.get((t, n), 0.0)
                              for n in QUAD_NAMES[len(FEATURES):])
          for t, b in TRUE_B.items()}


def _foods(n: int, seed: int, outliers: int = 0, bias: dict | None = None,
           form: str = "linear") -> list:
    """Reference foods whose estimates carry exactly the ``bias`` (TRUE_B unless given; of
    ``form``), plus a few gross failures, which the robust fit must not follow."""
    bias = TRUE_B if bias is None else bias
    rng = np.random.default_rng(seed)
    out = []
    for i in range(n):
        shape = ("cube", "ellipsoid", "sphere")[i % 3]
        size = float(rng.uniform(0.008, 0.025))
        g1, tau1, mu = float(rng.uniform(0.1, 0.8)), float(np.exp(rng.uniform(-0.7, 2.3))), \
            float(rng.uniform(0.1, 0.8))
        k_el = float(np.exp(rng.uniform(np.log(100), np.log(1e5))))
        truth = {"K1": (1 - g1) * k_el, "K2": g1 * k_el, "g1": g1, "tau1": tau1, "mu": mu}
        est = dict(truth)
        # the features use the estimates, so solve the bias fixed point by iteration
        for _ in range(50):
            x = design(features(shape, size, est), FEATURES, form)
            f = {t: math.exp(float(np.dot(bias[t], x))) for t in bias}
            gross = 1.5 if i < outliers else 1.0
            est = {"K1": (1 - g1 * f["g1"]) * k_el * f["K_el"], "K2": g1 * f["g1"] * k_el *
                   f["K_el"], "g1": g1 * f["g1"], "tau1": tau1 * f["tau1"] * gross, "mu": mu}
        out.append((shape, size, est, truth))
    return out


def test_fit_recovers_a_known_bias_and_apply_undoes_it() -> None:
    cal = fit_calibration(_foods(80, 1), f_scale=0.03)
    for t, b in TRUE_B.items():
        assert_allclose(cal.coefficients[t], b, atol=2e-3, err_msg=t)
    for shape, size, est, truth in _foods(10, 2):
        fixed, warns = cal.apply(shape, size, est)
        assert not warns
        for k in ("K1", "K2", "g1", "tau1"):
            assert_allclose(fixed[k], truth[k], rtol=3e-3, err_msg=k)
        assert_allclose(fixed["B"], truth["tau1"] * truth["K2"], rtol=5e-3)
        assert fixed["mu"] == est["mu"]


def test_a_few_gross_failures_do_not_steer_the_fit() -> None:
    cal = fit_calibration(_foods(80, 3, outliers=4), f_scale=0.03)
    assert_allclose(cal.coefficients["tau1"], TRUE_B["tau1"], atol=0.02)


def test_round_trip_and_bad_calibrations_are_refused() -> None:
    cal = fit_calibration(_foods(40, 4))
    assert Calibration.from_dict(cal.to_dict()) == cal
    with pytest.raises(EstimationError, match="tau1"):
        Calibration({"K_el": (0.0,) * len(FEATURES), "g1": (0.0,) * len(FEATURES)})
    with pytest.raises(EstimationError, match="features"):
        Calibration.from_dict({**cal.to_dict(), "features": ["1"]})
    with pytest.raises(EstimationError, match="at least"):
        fit_calibration(_foods(5, 5))
    with pytest.raises(EstimationError, match="shape"):
        features("blob", 0.01, _foods(1, 6)[0][2])
    with pytest.raises(EstimationError, match="tau1"):
        features("cube", 0.01, {**_foods(1, 6)[0][2], "tau1": math.nan})


def test_a_quadratic_fit_recovers_a_curved_bias_the_linear_one_cannot() -> None:
    """A bias that bends over the food space (stiffness squared, size times g1, ...) is
    recovered term by term by the quadratic form and undone to 0.3 %; the linear form fitted
    on the same foods leaves misses of several per cent."""
    foods = _foods(QUADRATIC_MIN_FOODS + 100, 11, bias=TRUE_Q, form="quadratic")
    quad = fit_calibration(foods, f_scale=0.03, form="quadratic")
    assert quad.form == "quadratic" and len(quad.coefficients["g1"]) == len(QUAD_NAMES) == 23
    for t, b in TRUE_Q.items():
        assert_allclose(quad.coefficients[t], b, atol=3e-3, err_msg=t)
    lin = fit_calibration(foods, f_scale=0.03)
    worst = {"quadratic": 0.0, "linear": 0.0}
    for shape, size, est, truth in _foods(20, 12, bias=TRUE_Q, form="quadratic"):
        for name, cal in (("quadratic", quad), ("linear", lin)):
            fixed, _ = cal.apply(shape, size, est)
            worst[name] = max(worst[name], *(abs(fixed[k] / truth[k] - 1)
                                            for k in ("K1", "K2", "g1", "tau1")))
    assert worst["quadratic"] < 3e-3 < 0.03 < worst["linear"], worst
    assert Calibration.from_dict(quad.to_dict()) == quad


def test_the_form_is_checked_and_a_quadratic_needs_enough_foods() -> None:
    with pytest.raises(EstimationError, match=f"at least {QUADRATIC_MIN_FOODS}"):
        fit_calibration(_foods(QUADRATIC_MIN_FOODS - 100, 13), form="quadratic")
    with pytest.raises(EstimationError, match="'cubic'"):
        fit_calibration(_foods(40, 13), form="cubic")
    lin = fit_calibration(_foods(40, 13))
    old = {k: v for k, v in lin.to_dict().items() if k != "form"}  # written before forms
    assert Calibration.from_dict(old) == lin and lin.form == "linear"
    with pytest.raises(EstimationError, match="'cubic'"):
        Calibration.from_dict({**lin.to_dict(), "form": "cubic"})
    with pytest.raises(EstimationError, match="23 finite numbers"):  # linear coefficients
        Calibration(lin.coefficients, form="quadratic")
    assert_allclose(design(np.arange(8.0), FEATURES, "quadratic")[8:11], [9.0, 12.0, 15.0])


def test_a_g1_pushed_to_one_is_held_and_said() -> None:
    cal = Calibration({"K_el": (0.0,) * 8, "g1": (-1.0,) + (0.0,) * 7, "tau1": (0.0,) * 8})
    fixed, warns = cal.apply("cube", 0.015, {"K1": 100.0, "K2": 900.0, "g1": 0.9, "tau1": 1.0,
                                             "mu": 0.3})
    assert fixed["g1"] == 0.99 and warns and "0.99" in warns[0]


def test_the_shipped_measure_calibration_is_fitted_on_tuning_foods() -> None:
    cal = PROBE_CALIBRATIONS["measure"]
    assert "tuning set, seed 1000" in cal.source and cal.n_foods >= 48


def test_extra_features_correct_only_their_targets_and_are_required_once_fitted() -> None:
    """With the trace's diagnostics, the fit recovers a tau1 bias that follows the drift pair
    and a K_el bias that follows the clamp fit's R^2, and no g1 bias where there is none;
    applying it needs the diagnostics, and says which is missing."""
    foods = _foods(80, 7)
    rng = np.random.default_rng(8)
    diags, biased = [], []
    for shape, size, est, truth in foods:
        d = {"drift_log_g1": float(rng.normal(0, 0.05)),
             "drift_log_tau1": float(rng.normal(0, 0.1)),
             "tau_span": float(np.exp(rng.uniform(-3, 0))), "r2_clamp": float(rng.uniform(0, 1))}
        diags.append(d)
        tau = est["tau1"] * math.exp(0.4 * d["drift_log_tau1"] - 0.3 * d["drift_log_g1"])
        k = math.exp(0.05 * math.log(max(1 - d["r2_clamp"], 1e-3)))
        biased.append((shape, size, {**est, "tau1": tau, "K1": est["K1"] * k,
                                     "K2": est["K2"] * k}, truth))
    cal = fit_calibration(biased, diagnostics=diags)
    assert cal.feature_names == FEATURES + EXTRA_FEATURES
    n = len(FEATURES)
    assert_allclose(cal.coefficients["tau1"][n:], (-0.3, 0.4, 0.0, 0.0), atol=0.02)
    assert_allclose(cal.coefficients["K_el"][n:], (0.0, 0.0, 0.0, 0.05), atol=0.01)
    # each target reads only its own extra features (TARGET_EXTRA_FEATURES): the rest are 0
    assert cal.coefficients["K_el"][n:n + 2] == (0.0, 0.0) == cal.coefficients["tau1"][n + 2:]
    assert cal.coefficients["g1"][n:] == (0.0,) * len(EXTRA_FEATURES)
    assert Calibration.from_dict(cal.to_dict()) == cal
    shape, size, est, truth = biased[0]
    fixed, _ = cal.apply(shape, size, est, diags[0])
    assert_allclose([fixed["tau1"], fixed["K1"]], [truth["tau1"], truth["K1"]], rtol=0.03)
    with pytest.raises(EstimationError, match="drift_log_g1"):
        cal.apply(shape, size, est)
    with pytest.raises(EstimationError, match="r2_clamp"):
        cal.apply(shape, size, est, {**diags[0], "r2_clamp": math.nan})
    with pytest.raises(EstimationError, match="one mapping per food"):
        fit_calibration(biased, diagnostics=diags[:-1])
