"""Tests of the K1/K2/B estimators (three-step and full least-squares fit)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose

from estimators.errors import EstimationError
from estimators.relaxation import (
    detect_contact,
    estimate_from_hold,
    estimate_full_fit,
    estimate_three_step,
    fit_hold_relaxation,
    infer_kinematics,
)
from estimators.sls import ClampGeometry, SLSParams, clamp_angle, moment_trace

GEOM = ClampGeometry(L=0.05, theta_0=0.17)
THETA_1 = 0.02
TRUE = SLSParams(K1=1150.0, K2=850.0, B=850.0 * 3.667)  # g1 = 0.425, tau1 = 3.667 s
ESTIMATORS = [estimate_three_step, estimate_full_fit]
# (omega rad/s, theta_d rad, hold s, t_start s): the study's 0.0244 rad at 0.01-0.04 rad/s, the
# diced-food angles at 0.1 rad/s, a t_d off the sample grid and a delayed start.
EXACT_CASES = [
    (0.01, 0.0244, 10.0, 0.0),
    (0.02, 0.0244, 15.0, 0.0),
    (0.03, 0.0244, 20.0, 0.0),
    (0.04, 0.0244, 12.0, 0.5),
    (0.1, 0.045, 10.0, 0.0),
    (0.1, 0.085, 10.0, 0.0),
    (0.1, 0.09, 20.0, 0.3),
    (0.1, 0.0244, 10.0, 0.0),
]


def make_trace(
    omega: float,
    theta_d: float,
    hold: float,
    t_start: float = 0.0,
    params: SLSParams = TRUE,
    fs: float = 100.0,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    t = np.arange(0.0, t_start + theta_d / omega + hold, 1.0 / fs)
    theta = clamp_angle(t, theta_d, omega, t_start)
    m = moment_trace(t, params, GEOM, THETA_1, theta_d, omega, t_start)
    return t, theta, m


def _rel_err(est, true: SLSParams = TRUE) -> np.ndarray:
    return np.array([est.K1 / true.K1, est.K2 / true.K2, est.B / true.B]) - 1.0


@pytest.mark.parametrize("estimator", ESTIMATORS)
@pytest.mark.parametrize(("omega", "theta_d", "hold", "t_start"), EXACT_CASES)
def test_exact_trace_recovers_parameters(estimator, omega, theta_d, hold, t_start) -> None:
    t, theta, m = make_trace(omega, theta_d, hold, t_start)
    est = estimator(t, theta, m, GEOM)
    assert est.reliable, est.warnings
    assert_allclose(_rel_err(est), 0.0, atol=1e-3)  # 0.1 %
    assert_allclose([est.g1, est.tau1], [0.425, 3.667], rtol=1e-3)
    assert_allclose(est.theta_1, THETA_1, atol=1e-5)
    assert_allclose([est.omega, est.theta_d], [omega, theta_d], rtol=1e-9)
    assert_allclose(est.t_d, t_start + theta_d / omega, atol=1e-9)
    assert est.r2_clamp > 0.9999 and est.r2_hold > 0.9999
    for name in ("K1", "K2", "B"):
        lo, hi = est.intervals[name]
        value = getattr(est, name)
        assert lo <= value <= hi
        assert hi - lo < 1e-3 * value  # noise-free: the intervals collapse


def test_full_fit_exact_is_essentially_exact() -> None:
    t, theta, m = make_trace(0.03, 0.0244, 10.0)
    est = estimate_full_fit(t, theta, m, GEOM)
    assert_allclose(_rel_err(est), 0.0, atol=1e-8)


def test_given_omega_and_theta_d_are_used() -> None:
    t, theta, m = make_trace(0.02, 0.05, 10.0, 0.2)
    est = estimate_full_fit(t, theta, m, GEOM, omega=0.02, theta_d=0.05)
    assert_allclose(_rel_err(est), 0.0, atol=1e-6)


def test_kinematics_and_contact_detection() -> None:
    t, theta, m = make_trace(0.03, 0.05, 10.0, t_start=0.37)
    kin = infer_kinematics(t, theta)
    assert_allclose([kin.omega, kin.theta_d, kin.t_start], [0.03, 0.05, 0.37], rtol=1e-9)
    contact = detect_contact(t, m, kin)
    assert_allclose(contact.theta_1, THETA_1, atol=1e-7)
    assert_allclose(contact.t_1, 0.37 + THETA_1 / 0.03, atol=1e-5)


def test_hold_fit_recovers_eq6() -> None:
    t, _, m = make_trace(0.02, 0.05, 15.0)
    hf = fit_hold_relaxation(t, m, 0.05 / 0.02)
    assert hf.relaxes
    assert_allclose(hf.lam, 1.0 / 3.667, rtol=1e-8)
    assert hf.r2 > 0.999999


@pytest.mark.parametrize(("omega", "theta_d", "tau1"), [(0.1, 0.045, 3.667), (0.01, 0.05, 1.5)])
def test_estimate_from_hold_is_exact_on_the_sls(omega, theta_d, tau1) -> None:
    """K1, K2, B, g1, tau1 from the hold alone, with the clamp's own relaxation divided out:
    exact on an SLS trace, where the bare g1 = A / (M_inf + A) is not (by ~T / 2 tau1 for a
    ramp of T s)."""
    params = SLSParams.from_prony(2000.0, 0.425, tau1)
    t, _, m = make_trace(omega, theta_d, 3.0, params=params)
    t_d = theta_d / omega
    est = estimate_from_hold(t, m, GEOM, THETA_1, theta_d, omega, t_d, settle=0.25)
    assert_allclose([est.K1, est.K2, est.B], [params.K1, params.K2, params.B], rtol=1e-6)
    assert_allclose([est.g1, est.tau1], [0.425, tau1], rtol=1e-6)
    assert est.fit.relaxes and est.fit.duration == pytest.approx(3.0 - 0.25, abs=0.02)
    hf = fit_hold_relaxation(t, m, t_d)
    bare = hf.A / (hf.M_inf + hf.A)
    ramp = (theta_d - THETA_1) / omega
    assert abs(bare / 0.425 - 1) > 0.2 * ramp / (2 * tau1)  # the correction matters


def test_estimate_from_hold_ignores_a_disturbed_clamp() -> None:
    """A clamp that does not rise as an SLS (a piece rocking as the blades close, then settling
    into the clamp with a fast extra decay early in the hold), fitted as the env's probe does
    (the first 0.1 s of the hold left out, clamp weight 0.3): the full fit's g1 and tau1 are
    off, the hold's past 0.25 s are not."""
    omega, theta_d = 0.1, 0.045
    t, theta, m = make_trace(omega, theta_d, 3.0)
    t_d = theta_d / omega
    clamp = (t > THETA_1 / omega) & (t <= t_d)
    hold = t > t_d
    m_bad = m.copy()
    m_bad[clamp] *= np.random.default_rng(7).uniform(0.3, 1.0, clamp.sum())
    m_bad[hold] += 0.2 * m.max() * np.exp(-(t[hold] - t_d) / 0.03)
    keep = ~((t > t_d) & (t < t_d + 0.1))
    fit = estimate_full_fit(t[keep], theta[keep], m_bad[keep], GEOM, omega=omega,
                            theta_d=theta_d, clamp_weight=0.3)
    assert abs(fit.g1 / 0.425 - 1) > 0.05, fit.g1  # the disturbance misleads the fit ...
    assert abs(fit.tau1 / 3.667 - 1) > 0.05, fit.tau1
    est = estimate_from_hold(t, m_bad, GEOM, fit.theta_1, theta_d, omega, t_d, settle=0.25)
    assert_allclose([est.g1, est.tau1], [0.425, 3.667], rtol=0.01)  # ... not the hold


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"settle": -0.1}, "settle"),
        ({"settle": float("nan")}, "settle"),
        ({"theta_1": 0.05}, "theta_1"),
        ({"t_d": float("inf")}, "t_d"),
        ({"omega": 0.0}, "omega"),
        ({"theta_d": -0.01}, "theta_d"),
        ({"settle": 2.95}, "hold"),
    ],
)
def test_estimate_from_hold_rejects_bad_input(kwargs, match) -> None:
    t, _, m = make_trace(0.1, 0.045, 3.0)
    args = {"theta_1": THETA_1, "theta_d": 0.045, "omega": 0.1, "t_d": 0.45, "settle": 0.25}
    args.update(kwargs)
    with pytest.raises(EstimationError, match=match):
        estimate_from_hold(t, m, GEOM, **args)


def test_estimate_from_hold_needs_a_relaxing_hold() -> None:
    params = SLSParams(K1=2000.0, K2=1e-9, B=1e-9)  # elastic: nothing relaxes
    t, _, m = make_trace(0.1, 0.045, 3.0, params=params)
    with pytest.raises(EstimationError, match="does not relax"):
        estimate_from_hold(t, m, GEOM, THETA_1, 0.045, 0.1, 0.45, settle=0.25)


def _noisy_trials(omega, theta_d, hold, n_trials, noise=0.01):
    t, theta, m = make_trace(omega, theta_d, hold)
    sigma = noise * m.max()
    errs, covered = [], []
    for seed in range(n_trials):
        rng = np.random.default_rng(seed)
        est = estimate_full_fit(t, theta, m + sigma * rng.standard_normal(m.size), GEOM)
        errs.append(_rel_err(est))
        covered.append(
            [
                est.intervals[k][0] <= v <= est.intervals[k][1]
                for k, v in (("K1", TRUE.K1), ("K2", TRUE.K2), ("B", TRUE.B))
            ]
        )
    return np.abs(np.array(errs)), np.array(covered)


def test_full_fit_with_noise_fast() -> None:
    """20 seeded trials, 1 % of M_peak white noise: a looser bound than the 100-trial test."""
    errs, covered = _noisy_trials(0.02, 0.0244, 15.0, 20)
    assert np.all(errs < 0.03)  # every trial within 3 %
    assert np.sum(np.all(errs < 0.02, axis=1)) >= 18  # >= 90 % of trials within 2 %
    assert np.all(covered.sum(axis=0) >= 16)  # 95 % intervals: >= 16 / 20 cover the truth
    assert np.all(np.median(errs, axis=0) < 0.01)


@pytest.mark.parametrize(("omega", "theta_d", "hold"), [(0.01, 0.0244, 10.0), (0.1, 0.09, 10.0)])
def test_full_fit_with_noise_100_trials(omega, theta_d, hold) -> None:
    """100 seeded trials (~1 s): within 2 % in >= 90 trials, intervals cover >= 90 / 100."""
    errs, covered = _noisy_trials(omega, theta_d, hold, 100)
    assert np.sum(np.all(errs < 0.02, axis=1)) >= 90
    assert np.all(covered.sum(axis=0) >= 90), covered.sum(axis=0)
    assert np.all(errs.mean(axis=0) < 0.01)


@pytest.mark.slow
@pytest.mark.parametrize(
    ("omega", "theta_d", "hold"),
    [(0.02, 0.0244, 15.0), (0.03, 0.0244, 20.0), (0.04, 0.0244, 10.0), (0.1, 0.045, 12.0)],
)
def test_full_fit_with_noise_sweep(omega, theta_d, hold) -> None:
    """200 seeded trials per setup. The 95 % intervals stay calibrated (>= 90 % coverage); the
    2 % accuracy is a property of the data, not only of the fit: at 0.04 rad/s with a 10 s hold
    (11 clamp samples after contact) 174 / 200 trials are within 2 % on all of K1, K2, B."""
    errs, covered = _noisy_trials(omega, theta_d, hold, 200)
    assert np.sum(np.all(errs < 0.02, axis=1)) >= 170
    assert np.all(covered.sum(axis=0) >= 180), covered.sum(axis=0)
    assert np.all(errs.mean(axis=0) < 0.0125)  # mean |error|; observed max 1.003 % (B)


def test_three_step_with_noise_is_usable() -> None:
    """The study's method on 1 % noise: median error < 2 % (it is the less precise method)."""
    t, theta, m = make_trace(0.02, 0.0244, 15.0)
    errs = []
    for seed in range(20):
        rng = np.random.default_rng(seed)
        est = estimate_three_step(t, theta, m + 0.01 * m.max() * rng.standard_normal(m.size), GEOM)
        errs.append(_rel_err(est))
    assert np.all(np.median(np.abs(errs), axis=0) < 0.02)


# ------------------------------------------------------------------------------- bad inputs


@pytest.fixture
def good() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    return make_trace(0.02, 0.0244, 10.0)


@pytest.mark.parametrize("estimator", ESTIMATORS)
class TestBadInputs:
    def test_too_short(self, estimator, good) -> None:
        t, theta, m = good
        with pytest.raises(EstimationError, match="too short"):
            estimator(t[:5], theta[:5], m[:5], GEOM)

    def test_mismatched_lengths(self, estimator, good) -> None:
        t, theta, m = good
        with pytest.raises(EstimationError, match=r"mismatched lengths.*'M'"):
            estimator(t, theta, m[:-3], GEOM)

    @pytest.mark.parametrize("bad", [np.nan, np.inf])
    def test_non_finite(self, estimator, good, bad) -> None:
        t, theta, m = good
        m = m.copy()
        m[500] = bad
        with pytest.raises(EstimationError, match=r"'M' has 1 non-finite.*index 500"):
            estimator(t, theta, m, GEOM)
        theta = theta.copy()
        theta[7] = bad
        with pytest.raises(EstimationError, match="'theta' has 1 non-finite"):
            estimator(t, theta, good[2], GEOM)

    def test_unsorted_time(self, estimator, good) -> None:
        t, theta, m = good
        t = t.copy()
        t[[100, 101]] = t[[101, 100]]
        with pytest.raises(EstimationError, match="unsorted"):
            estimator(t, theta, m, GEOM)

    def test_repeated_time(self, estimator, good) -> None:
        t, theta, m = good
        t = t.copy()
        t[101] = t[100]
        with pytest.raises(EstimationError, match="repeated at index 101"):
            estimator(t, theta, m, GEOM)

    def test_no_contact_zero(self, estimator, good) -> None:
        t, theta, m = good
        with pytest.raises(EstimationError, match="no contact"):
            estimator(t, theta, np.zeros_like(m), GEOM)

    def test_no_contact_noise_only(self, estimator, good) -> None:
        t, theta, m = good
        noise = 1e-4 * np.random.default_rng(0).standard_normal(m.size)
        with pytest.raises(EstimationError, match="no contact"):
            estimator(t, theta, noise, GEOM)

    def test_no_hold(self, estimator) -> None:
        t = np.arange(0.0, 2.4, 0.01)
        theta = 0.01 * t
        m = moment_trace(t, TRUE, GEOM, 0.01, 0.024, 0.01)
        with pytest.raises(EstimationError, match="no hold phase"):
            estimator(t, theta, m, GEOM)

    def test_theta_never_grows(self, estimator, good) -> None:
        t, _, m = good
        with pytest.raises(EstimationError, match="theta never grows"):
            estimator(t, np.zeros_like(t), m, GEOM)

    def test_never_relaxes_is_flagged(self, estimator) -> None:
        # Purely elastic food: B so large that tau1 = 1e6 s.
        elastic = SLSParams(K1=1150.0, K2=850.0, B=850.0 * 1e6)
        t, theta, m = make_trace(0.02, 0.0244, 10.0, params=elastic)
        est = estimator(t, theta, m, GEOM)
        assert not est.reliable
        assert any("never relaxes" in w for w in est.warnings)

    def test_short_hold_is_flagged(self, estimator) -> None:
        t, theta, m = make_trace(0.02, 0.0244, 2.0)
        est = estimator(t, theta, m, GEOM)
        assert not est.reliable
        assert any("shorter than tau1" in w for w in est.warnings)


def test_hold_fit_with_drift_recovers_an_exponential_plus_a_line() -> None:
    """A held moment that relaxes and also falls linearly (a creeping contact): the drift fit
    recovers all four terms, the plain fit reads the line as a longer decay, and on a pure
    exponential the drift fit finds no line."""
    s = np.linspace(0.0, 20.0, 2001)
    t_d = 2.0
    m_inf, a, lam, c = 0.05, 0.03, 1.0 / 1.5, -4e-4
    t = t_d + s
    hf = fit_hold_relaxation(t, m_inf + a * np.exp(-lam * s) + c * s, t_d - 1e-9, drift=True)
    assert_allclose([hf.M_inf, hf.A, hf.lam, hf.drift], [m_inf, a, lam, c], rtol=1e-6)
    assert hf.relaxes and hf.r2 > 0.999999
    plain = fit_hold_relaxation(t, m_inf + a * np.exp(-lam * s) + c * s, t_d - 1e-9)
    assert plain.drift == 0.0 and 1.0 / plain.lam > 1.05 * 1.5  # the line lengthens tau
    pure = fit_hold_relaxation(t, m_inf + a * np.exp(-lam * s), t_d - 1e-9, drift=True)
    assert abs(pure.drift) < 1e-9 and pure.lam == pytest.approx(lam, rel=1e-8)
    assert_allclose(pure.cov.shape, (3, 3))


def test_drift_fit_from_a_given_plain_fit_is_the_same_fit() -> None:
    """``plain=`` skips the plain fit the drift refit starts from: on a noisy creeping hold
    the result is the one fitted from scratch, to the last bit."""
    rng = np.random.default_rng(3)
    s = np.linspace(0.0, 20.0, 400)
    t_d = 2.0
    m = 0.05 + 0.03 * np.exp(-s / 1.5) - 4e-4 * s + 2e-4 * rng.standard_normal(s.size)
    plain = fit_hold_relaxation(t_d + s, m, t_d - 1e-9)
    scratch = fit_hold_relaxation(t_d + s, m, t_d - 1e-9, drift=True)
    given = fit_hold_relaxation(t_d + s, m, t_d - 1e-9, drift=True, plain=plain)
    for name in ("M_inf", "A", "lam", "r2", "duration", "relaxes", "drift"):
        assert getattr(given, name) == getattr(scratch, name), name
    np.testing.assert_array_equal(given.cov, scratch.cov)
    assert given.drift < 0.0


def _creeping_hold(seed: int) -> tuple[np.ndarray, np.ndarray, float]:
    """A noisy hold that relaxes slowly (rate 0.01-0.05 1/s over 20 s) while its contact
    creeps (a line of +-1e-3 N m/s): the exponential and the line nearly coincide.  Returns
    the hold's times, moment and true rate."""
    rng = np.random.default_rng(seed)
    s = np.linspace(0.0, 20.0, 4000)
    lam = float(rng.uniform(0.01, 0.05))
    y = 0.01 + 0.02 * np.exp(-lam * s) + rng.uniform(-1e-3, 1e-3) * s
    return s, y + 2e-4 * rng.standard_normal(s.size), lam


def _projected_rss(s: np.ndarray, y: np.ndarray, lam: float) -> float:
    basis = np.column_stack((np.ones_like(s), np.exp(-lam * s), s))
    r = y - basis @ np.linalg.lstsq(basis, y, rcond=None)[0]
    return float(r @ r)


@pytest.mark.parametrize("seed", [0, 1, 2, 4])
def test_decay_line_fit_is_the_least_squares_minimum(seed: int) -> None:
    """The variable-projection fit of an exponential plus a line lands on the minimum: its
    residual is no more than that of any rate on a dense grid (1e-9 relative), and it is
    Levenberg-Marquardt's converged fit (rate and parameters to 1e-5, standard errors to
    1e-4) on these creeping holds, where the bounded trust-region solver may run out of
    evaluations (seed 0).  (Seed 3's best rate is at the search's edge: see the next test.)
    The two solvers stop within their tolerances of each other: at most 6.6e-7 apart with
    numpy's AVX-512 kernels, 2.0e-6 (seed 0's intercept) with its AVX2 ones."""
    from estimators.relaxation import (
        _exp_drift_jac,
        _exp_drift_model,
        _fit_decay_projected,
        _lm_decay,
    )

    s, y, lam = _creeping_hold(seed)
    popt, pcov = _fit_decay_projected(s, y, line=True)
    best = _projected_rss(s, y, popt[2])
    dense = min(_projected_rss(s, y, r) for r in np.geomspace(lam / 30.0, lam * 30.0, 3000))
    assert best <= dense * (1.0 + 1e-9)
    lm = _lm_decay(_exp_drift_model, _exp_drift_jac, s, y, (0.02, 0.01, 0.2, 0.0))
    assert lm is not None
    assert_allclose(popt, lm[0], rtol=1e-5, atol=1e-9)
    assert_allclose(np.sqrt(np.diag(pcov)), np.sqrt(np.diag(lm[1])), rtol=1e-4)


@pytest.mark.parametrize("seed", range(4))
def test_decay_search_is_the_bounded_least_squares_fit(seed: int) -> None:
    """The search over the rate lands on eq. 6's minimum where Levenberg-Marquardt does
    (noisy holds over the tau1 range; rate and parameters to 1e-6, standard errors to
    1e-4), so the hold fit's fallback changes no converged fit."""
    from estimators.relaxation import _exp_jac, _exp_model, _fit_decay_projected, _lm_decay

    rng = np.random.default_rng(seed)
    tau1 = float(rng.uniform(0.5, 10.0))
    s = np.linspace(0.0, 20.0, 500)
    y = 0.05 + 0.03 * np.exp(-s / tau1) + 3e-4 * rng.standard_normal(s.size)
    popt, pcov = _fit_decay_projected(s, y, line=False)
    lm = _lm_decay(_exp_model, _exp_jac, s, y, (y[-1], y[0] - y[-1], 1.0 / tau1))
    assert lm is not None
    assert_allclose(popt, lm[0], rtol=1e-6, atol=1e-9)
    assert_allclose(np.sqrt(np.diag(pcov)), np.sqrt(np.diag(lm[1])), rtol=1e-4)


def test_decay_line_fit_says_when_the_decay_is_not_separable() -> None:
    """A hold that bends like a parabola (a creep that slows): an exponential plus a line
    fits it ever better as the rate goes to 0 and the amplitude to infinity, so there is no
    decay to separate.  The fit raises rather than return the rate at the edge of its
    search (the drift refit then keeps the plain fit and no drift), with or without noise."""
    from estimators.relaxation import _fit_decay_projected

    s = np.linspace(0.0, 20.0, 2000)
    for noise in (0.0, 1e-6):
        y = 0.03 - 2e-4 * s + 3e-6 * s**2 + noise * np.random.default_rng(5).standard_normal(
            s.size)
        with pytest.raises(RuntimeError, match="not separable"):
            _fit_decay_projected(s, y, line=True)


def test_drift_refit_falls_back_to_the_decay_line_fit(monkeypatch: pytest.MonkeyPatch) -> None:
    """Where Levenberg-Marquardt fails on the drift refit, the refit is the variable-
    projection fit: same rate, amplitude and line (1e-6) as Levenberg-Marquardt's own
    converged fit of the same creeping hold."""
    import estimators.relaxation as relaxation

    s, y, _ = _creeping_hold(0)
    t_d = 2.0
    plain = fit_hold_relaxation(t_d + s, y, t_d - 1e-9)
    reference = fit_hold_relaxation(t_d + s, y, t_d - 1e-9, drift=True, plain=plain)
    lm = relaxation._lm_decay
    monkeypatch.setattr(relaxation, "_lm_decay",
                        lambda model, *a: None if model is relaxation._exp_drift_model
                        else lm(model, *a))
    fallback = fit_hold_relaxation(t_d + s, y, t_d - 1e-9, drift=True, plain=plain)
    assert fallback.drift != 0.0
    assert_allclose([fallback.M_inf, fallback.A, fallback.lam, fallback.drift],
                    [reference.M_inf, reference.A, reference.lam, reference.drift],
                    rtol=1e-6)


def _bounded_trf_fit(s: np.ndarray, y: np.ndarray, p0: tuple[float, ...]) -> np.ndarray:
    """The reference: eq. 6 fitted by scipy's bounded trust-region solver alone (rate >= 0)."""
    from scipy.optimize import curve_fit

    def model(x: np.ndarray, m_inf: float, a: float, lam: float) -> np.ndarray:
        return m_inf + a * np.exp(-lam * x)

    popt, _ = curve_fit(model, s, y, p0=p0, bounds=((-np.inf, -np.inf, 0.0), np.inf),
                        method="trf", x_scale="jac", xtol=1e-14, ftol=1e-14, gtol=1e-14)
    return popt


@pytest.mark.parametrize("seed", range(6))
def test_hold_fit_is_the_bounded_least_squares_fit(seed: int) -> None:
    """The hold fit (Levenberg-Marquardt first) lands on the bounded solver's minimum: noisy
    holds over the tau1 range, rate to 1e-6 relative and M_inf, A to 1e-6 of M(t_d)."""
    rng = np.random.default_rng(seed)
    tau1 = float(rng.uniform(0.5, 10.0))
    s = np.linspace(0.0, 20.0, 500)
    y = 0.05 + 0.03 * np.exp(-s / tau1) + 3e-4 * rng.standard_normal(s.size)
    hf = fit_hold_relaxation(2.0 + s, y, 2.0 - 1e-9)
    ref = _bounded_trf_fit(s, y, (y[-1], y[0] - y[-1], 1.0 / tau1))
    assert hf.lam == pytest.approx(ref[2], rel=1e-6)
    assert_allclose([hf.M_inf, hf.A], ref[:2], atol=1e-6 * 0.08)


def test_hold_fit_keeps_the_rate_non_negative_where_lm_finds_a_negative_one() -> None:
    """A held moment that falls ever faster (a negative decay rate fits it best): the
    unbounded Levenberg-Marquardt fit converges to rate -0.25, which is not kept; the search
    over rates >= 0 runs instead (here its best rate is the smallest searched, so
    ``_fit_decay`` raises rather than return a rate at that edge), and the hold fit keeps
    the rate >= 0 and says the hold does not relax."""
    from estimators.relaxation import _fit_decay

    rng = np.random.default_rng(0)
    s = np.linspace(0.0, 10.0, 400)
    y = 0.05 - 0.001 * np.exp(s / 4.0) + 1e-5 * rng.standard_normal(s.size)
    with pytest.raises(RuntimeError, match="not separable"):
        _fit_decay(s, y, (0.05, -0.001, 0.1))
    hf = fit_hold_relaxation(2.0 + s, y, 2.0 - 1e-9)
    assert hf.lam >= 0.0
    assert not hf.relaxes


@pytest.mark.parametrize(("kwargs", "says"), [
    ({"t_d": -math.inf}, "t_d must be a finite time"),
    ({"t_d": math.nan}, "t_d must be a finite time"),
    ({"drift": [1]}, "drift must be True or False"),
    ({"drift": np.ones(3)}, "drift must be True or False"),
    ({"drift": True, "plain": [0, 1]}, "plain must be a HoldFit"),
])
def test_hold_fit_refuses_bad_arguments_naming_them(kwargs: dict, says: str) -> None:
    """Each bad argument is the package's error naming it, not numpy's LinAlgError, an
    ambiguous truth value or an AttributeError."""
    t = np.arange(30.0)
    args = {"t": t, "M": 1.0 + np.exp(-t / 5.0), "t_d": 1.0, **kwargs}
    with pytest.raises(EstimationError, match=says):
        fit_hold_relaxation(**args)
