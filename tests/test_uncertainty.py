"""Intervals with model error (estimators.uncertainty) on synthetic clamp-and-hold traces."""

from __future__ import annotations

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose

from estimators import ClampGeometry, EstimationError, SLSParams, moment_trace
from estimators.uncertainty import drift_diagnostics, hold_with_intervals, log_interval

GEOM = ClampGeometry(L=0.0385, theta_0=0.0)
THETA_1, THETA_D, OMEGA = 0.002, 0.02, 0.1
T_D = THETA_D / OMEGA


def _trace(g1: float, tau1: float, hold: float = 20.0) -> tuple[np.ndarray, np.ndarray, SLSParams]:
    params = SLSParams.from_prony(3000.0, g1, tau1)
    t = np.concatenate((np.arange(0.0, T_D, 0.01), T_D + np.geomspace(0.01, hold, 300)))
    m = moment_trace(t, params, GEOM, THETA_1, THETA_D, OMEGA)
    return t, m, params


@pytest.mark.parametrize(("g1", "tau1"), [(0.1, 0.5), (0.425, 3.667), (0.8, 10.0)])
def test_exact_traces_recover_the_parameters_with_tight_intervals(g1: float, tau1: float) -> None:
    t, m, params = _trace(g1, tau1)
    out = hold_with_intervals(t, m, GEOM, THETA_1, THETA_D, OMEGA, T_D, settle=0.25)
    est = out.estimate
    assert_allclose([est.g1, est.tau1], [g1, tau1], rtol=1e-4)
    assert_allclose([est.K1, est.K2, est.B], [params.K1, params.K2, params.B], rtol=1e-3)
    for name, true in (("g1", g1), ("tau1", tau1), ("K1", params.K1)):
        lo, hi = out.intervals[name]
        # An exact exponential is fitted to round-off, so the interval may be as narrow as
        # round-off: it must reach the truth to within 1e-12 relative.
        assert lo <= true * (1 + 1e-12) and hi >= true * (1 - 1e-12)
        assert hi / lo - 1 < 1e-3  # an exact exponential: no noise, no window dependence


def test_window_shifts_see_a_drift_the_noise_part_misses() -> None:
    """A slow drift (no viscoelastic origin) bends the hold: the estimate moves with the
    window, so the model part widens the interval enough to cover the truth."""
    t, m, _ = _trace(0.3, 2.0)
    drift = -0.01 * m.max() * np.clip(t - T_D, 0, None) / 20.0
    out = hold_with_intervals(t, m + drift, GEOM, THETA_1, THETA_D, OMEGA, T_D, settle=0.25)
    assert out.sd_model["tau1"] > 3 * out.sd_noise["tau1"]
    for name, true in (("g1", 0.3), ("tau1", 2.0)):
        lo, hi = out.intervals[name]
        assert lo <= true <= hi, (name, lo, hi)


def test_correlated_noise_intervals_cover_about_95_percent() -> None:
    """AR(1) noise (rho 0.8, 0.5 % of the peak): over 60 seeded traces the 95 % intervals of
    g1 and tau1 each cover the truth on at least 85 % and the median estimate is unbiased
    within 2 %."""
    rng = np.random.default_rng(11)
    t, m, _ = _trace(0.4, 2.5)
    hits = {"g1": 0, "tau1": 0}
    tau_est = []
    for _ in range(60):
        e = np.zeros(t.size)
        w = rng.standard_normal(t.size) * 0.005 * m.max() * math.sqrt(1 - 0.8**2)
        for i in range(1, t.size):
            e[i] = 0.8 * e[i - 1] + w[i]
        out = hold_with_intervals(t, m + e, GEOM, THETA_1, THETA_D, OMEGA, T_D, settle=0.25)
        tau_est.append(out.estimate.tau1)
        for name, true in (("g1", 0.4), ("tau1", 2.5)):
            lo, hi = out.intervals[name]
            hits[name] += lo <= true <= hi
    assert hits["g1"] >= 51 and hits["tau1"] >= 51, hits
    assert abs(np.median(tau_est) / 2.5 - 1) < 0.02


def test_systematic_part_adds_in_quadrature_and_bad_values_are_refused() -> None:
    t, m, _ = _trace(0.3, 2.0)
    out = hold_with_intervals(t, m, GEOM, THETA_1, THETA_D, OMEGA, T_D, settle=0.25,
                              systematic={"tau1": 0.05})
    lo, hi = out.intervals["tau1"]
    assert_allclose(math.log(hi / lo) / (2 * 1.959963984540054), 0.05, rtol=1e-3)
    with pytest.raises(EstimationError, match="systematic"):
        hold_with_intervals(t, m, GEOM, THETA_1, THETA_D, OMEGA, T_D, systematic={"mu": 0.1})
    with pytest.raises(EstimationError, match="scale"):
        hold_with_intervals(t, m, GEOM, THETA_1, THETA_D, OMEGA, T_D, scale=0.0)


def test_log_interval() -> None:
    assert_allclose(log_interval(2.0, 0.1), (2.0 * math.exp(-0.196), 2.0 * math.exp(0.196)),
                    rtol=1e-3)
    assert all(math.isnan(v) for v in log_interval(-1.0, 0.1))
    assert all(math.isnan(v) for v in log_interval(2.0, 0.1, z=math.inf))
    # a half-width past a float's exponential: no information, not an OverflowError
    assert log_interval(1.0, 1e300) == (0.0, math.inf)
    assert log_interval(1.0, -1e300) == (0.0, math.inf)
    assert log_interval(3.0, 350.0, z=2.0) == pytest.approx((3.0 * math.exp(-700.0),
                                                            3.0 * math.exp(700.0)))



def test_drift_diagnostics_see_a_creeping_contact_and_not_a_clean_hold() -> None:
    """``drift_log_tau1`` (plain fit's tau1 over the drift fit's) is ~0 on an SLS hold and
    clearly positive where the held moment also falls linearly; 0 where no fit is possible."""
    t, m, _ = _trace(0.425, 1.5)
    args = (GEOM, THETA_1, THETA_D, OMEGA, T_D)
    clean = drift_diagnostics(t, m, *args, settle=0.25)
    assert abs(clean["drift_log_tau1"]) < 1e-4 and abs(clean["drift_log_g1"]) < 1e-4
    creep = m - 0.002 * m.max() * np.clip(t - T_D, 0.0, None)  # 0.2 % of the peak a second
    assert drift_diagnostics(t, creep, *args, settle=0.25)["drift_log_tau1"] > 0.05
    short = t <= T_D + 0.3
    assert drift_diagnostics(t[short], m[short], *args, settle=0.25) == {
        "drift_log_g1": 0.0, "drift_log_tau1": 0.0}
    out = hold_with_intervals(t, creep, *args, settle=0.25)
    assert out.diagnostics["drift_log_tau1"] == drift_diagnostics(
        t, creep, *args, settle=0.25)["drift_log_tau1"]
