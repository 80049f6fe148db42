"""Intervals that include model error, not only sensor noise.

A least-squares covariance ``s^2 (J^T J)^-1`` says how much white noise moves a fit.  A
simulated or real clamp adds errors the model does not have: contact events that step the
moment, a piece still settling into the clamp, a slow drift.  They show up as residuals that
are correlated in time and as estimates that move when the window of the fit moves.  The
intervals here add both:

* the noise part, from the Jacobian, inflated by the residuals' lag-1 autocorrelation
  ``rho`` (an effective sample size ``n (1 - rho) / (1 + rho)``);
* the model part, the largest change of each estimate when the hold window starts later or
  ends earlier (:data:`WINDOW_SHIFTS`): a pure exponential gives the same answer on every
  window, a distorted one does not.

Their root-sum-square, times :data:`INTERVAL_SCALE`, and a method's validated systematic
uncertainty (``systematic``, what a validation against foods of known parameters showed it
misses by beyond what its own trace reveals, as a metrologist's type B uncertainty) in
quadrature, is the standard deviation of the log of each estimate; the 95 % interval is
``exp(+-1.96 sd)`` around it.  The simulator's probes take theirs from the validation
harness's tuning foods (``fetch_env.probes.PROBE_SYSTEMATIC_SD``) and report the coverage it
gives on the reporting foods.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike

from estimators.errors import EstimationError, check_traces, instance, mapping, real
from estimators.relaxation import (
    ClampKinematics,
    HoldEstimate,
    _three_step_core,
    estimate_from_hold,
)
from estimators.sls import ClampGeometry

__all__ = ["DRIFT_DIAGNOSTICS", "INTERVAL_SCALE", "MAX_LOG_HALF_WIDTH", "WINDOW_SHIFTS",
           "HoldWithIntervals", "drift_diagnostics", "hold_diagnostics", "hold_with_intervals",
           "log_interval"]

Z95 = 1.959963984540054
# [log units] the widest half-width an interval is computed for: math.exp overflows a
# float just above 709; past it an interval is (0, inf)
MAX_LOG_HALF_WIDTH = 700.0
INTERVAL_SCALE = 1.0
# (share of the hold span dropped at the start, share dropped at the end)
WINDOW_SHIFTS: tuple[tuple[float, float], ...] = ((0.15, 0.0), (0.0, 0.3))
_NAMES = ("K1", "K2", "B", "g1", "tau1")
DRIFT_DIAGNOSTICS = ("drift_log_g1", "drift_log_tau1")


@dataclass
class HoldWithIntervals:
    """A hold estimate with 95 % intervals and the parts of its uncertainty.

    Attributes:
        estimate: the estimate on the full hold window.
        intervals: name -> (low, high), 95 %.
        sd_noise, sd_model: name -> standard deviation of the log estimate from noise and
            from the window shifts.
        alternates: the estimates on the shifted windows (those that gave one).
        diagnostics: what the trace says about how well eq. 6 fits it
            (:func:`hold_diagnostics`, :func:`drift_diagnostics`), the inputs of a
            calibration and its error model (:mod:`estimators.calibration`).
    """

    estimate: HoldEstimate
    intervals: dict[str, tuple[float, float]]
    sd_noise: dict[str, float]
    sd_model: dict[str, float]
    alternates: list[HoldEstimate] = field(default_factory=list)
    diagnostics: dict[str, float] = field(default_factory=dict)


def log_interval(value: float, sd_log: float, z: float = Z95) -> tuple[float, float]:
    """``value * exp(+-z sd_log)`` (a positive quantity's interval on the log scale); NaN
    where ``value`` is not finite and positive or ``sd_log`` or ``z`` not finite; (0, inf)
    where the half-width ``|z sd_log|`` is past what a float's exponential holds (~709)."""
    value, sd_log, z = real("value", value), real("sd_log", sd_log), real("z", z)
    if not (math.isfinite(value) and value > 0 and math.isfinite(sd_log)
            and math.isfinite(z)):
        return (math.nan, math.nan)
    half = abs(z * sd_log)
    if half > MAX_LOG_HALF_WIDTH:
        return (0.0, math.inf)
    return (value * math.exp(-half), value * math.exp(half))


def _lag1(r: np.ndarray) -> float:
    if r.size < 4:
        return 0.0
    r = r - r.mean()
    den = float(r @ r)
    return float(np.clip((r[1:] @ r[:-1]) / den, 0.0, 0.95)) if den > 0 else 0.0


def hold_diagnostics(est: HoldEstimate, t: np.ndarray, m: np.ndarray, t_start: float
                     ) -> dict[str, float]:
    """How far the hold past ``t_start`` is from one exponential, in numbers an error model
    can use (all dimensionless):

    * ``rho``: lag-1 autocorrelation of the residuals (a bent trace leaves runs of one sign);
    * ``log_rms``: log of the residuals' rms over the relaxing part ``|A|``;
    * ``end_drift``: the residuals' mean over the last fifth of the hold less that over the
      fifth before it, over ``|A|`` (a drift the exponential cannot follow ends the hold
      with a slope of the residuals);
    * ``log_tau_span``: log of the fitted decay time over the hold's span (a decay slow
      against the hold is extrapolated, a fast one leaves few samples);
    * ``log_relax``: log of the relaxing share ``|A| / (M_inf + |A|)`` of the held moment.
    """
    instance("est", est, HoldEstimate, "a HoldEstimate (estimate_from_hold)")
    t_start = real("t_start", t_start)
    t, traces = check_traces(t, min_samples=1, m=m)
    m = traces["m"]
    hf = est.fit
    sel = t > t_start
    s, y = t[sel] - t_start, m[sel]
    resid = y - hf.model(s)
    a = max(abs(hf.A), 1e-300)
    span = float(s[-1]) if s.size else 0.0
    late = s > 0.8 * span
    before = (s > 0.6 * span) & ~late
    drift = (float(resid[late].mean() - resid[before].mean()) / a
             if late.any() and before.any() else 0.0)
    return {
        "rho": _lag1(resid),
        "log_rms": math.log(max(float(np.sqrt(np.mean(resid**2))) / a, 1e-9)),
        "end_drift": drift,
        "log_tau_span": math.log(max(est.tau1, 1e-9) / max(span, 1e-9)),
        "log_relax": math.log(max(a / max(abs(hf.M_inf) + a, 1e-300), 1e-9)),
    }


def _noise_sd(est: HoldEstimate, t: np.ndarray, m: np.ndarray, geometry: ClampGeometry,
              theta_1: float, theta_d: float, omega: float, t_d: float, settle: float
              ) -> dict[str, float]:
    """Log-sd of each estimate from the hold fit's covariance (autocorrelation-inflated),
    carried through the estimator by the delta method: a numerical Jacobian of
    ``log(K1, K2, B, g1, tau1)`` with respect to the fit's ``(M_inf, A, lam)``."""
    hf = est.fit
    t_start = t_d + settle
    sel = t > t_start
    s, y = t[sel] - t_start, m[sel]
    resid = y - hf.model(s)
    rho = _lag1(resid)
    cov = np.asarray(hf.cov) * (1 + rho) / (1 - rho)
    if not np.all(np.isfinite(cov)):
        return dict.fromkeys(_NAMES, math.inf)
    kin = ClampKinematics(omega=omega, theta_d=theta_d, t_start=t_d - theta_d / omega,
                          t_d=t_d, theta_noise=0.0)

    def logs(p: np.ndarray) -> np.ndarray:
        m_inf, a, lam = (float(v) for v in p)
        k1, k2, b = _three_step_core(hf, geometry, theta_1, kin, m_inf=m_inf,
                                     a=a * math.exp(lam * settle), lam=lam)
        return np.log([k1, k2, b, k2 / (k1 + k2), b / k2])

    p0 = np.array([hf.M_inf, hf.A, hf.lam])
    steps = 1e-3 * np.sqrt(np.maximum(np.diag(cov), 0.0)) + 1e-9 * np.abs(p0)
    try:
        f0 = logs(p0)
        jac = np.column_stack([(logs(p0 + h * e) - f0) / h
                               for h, e in zip(steps, np.eye(3), strict=True)])
    except (EstimationError, ArithmeticError, ValueError):
        return dict.fromkeys(_NAMES, math.inf)  # not identified near the fit: say so
    var = np.einsum("ij,jk,ik->i", jac, cov, jac)
    return {k: float(math.sqrt(max(v, 0.0))) for k, v in zip(_NAMES, var, strict=True)}


def hold_with_intervals(
    t: ArrayLike,
    M: ArrayLike,
    geometry: ClampGeometry,
    theta_1: float,
    theta_d: float,
    omega: float,
    t_d: float,
    settle: float = 0.0,
    scale: float = INTERVAL_SCALE,
    systematic: dict[str, float] | None = None,
    with_drift_diagnostics: bool = True,
) -> HoldWithIntervals:
    """:func:`estimators.estimate_from_hold` with 95 % intervals that include model error.

    Args: as :func:`estimators.estimate_from_hold`; ``scale`` multiplies the noise and the
    window parts of the standard deviation (see the module docstring); ``systematic`` gives,
    by name, a validated systematic log-sd of the measurement method (a type B uncertainty:
    what a validation against known foods showed the method misses by beyond what the trace
    itself reveals), added in quadrature; ``with_drift_diagnostics`` adds
    :func:`drift_diagnostics` to the diagnostics (one more fit, ~4 ms).

    Raises:
        EstimationError: as :func:`estimators.estimate_from_hold` on the full window.
    """
    if not (math.isfinite(real("scale", scale)) and scale > 0):
        raise EstimationError(f"scale must be finite and > 0, got {scale!r}")
    if systematic is not None:
        mapping("systematic", systematic)
    tt, traces = check_traces(t, M=M)
    mm = traces["M"]
    args = (geometry, theta_1, theta_d, omega, t_d)
    est = estimate_from_hold(tt, mm, *args, settle=settle)
    span = float(tt[-1]) - (t_d + settle)
    alternates = []
    for head, tail in WINDOW_SHIFTS:
        keep = tt <= tt[-1] - tail * span + 1e-12
        try:
            alternates.append(estimate_from_hold(tt[keep], mm[keep], *args,
                                                 settle=settle + head * span))
        except (EstimationError, ArithmeticError):
            continue  # a window too short to fit says nothing either way
    noise = _noise_sd(est, tt, mm, geometry, theta_1, theta_d, omega, t_d, settle)
    model = {}
    for k in _NAMES:
        v0 = getattr(est, k)
        shifts = [abs(math.log(getattr(a, k) / v0)) for a in alternates
                  if getattr(a, k) > 0 and math.isfinite(getattr(a, k)) and v0 > 0]
        model[k] = max(shifts) if shifts else (math.inf if len(alternates) < 1 else 0.0)
    floor = systematic or {}
    for k, v in floor.items():
        if k not in _NAMES or isinstance(v, bool) or not isinstance(v, int | float) or not (
                math.isfinite(v) and v >= 0):
            raise EstimationError(f"systematic[{k!r}] must name one of {_NAMES} with a finite "
                                  f"sd >= 0, got {v!r}")
    intervals = {k: log_interval(getattr(est, k), math.hypot(
        scale * math.hypot(noise[k], model[k]), floor.get(k, 0.0))) for k in _NAMES}
    diag = hold_diagnostics(est, tt, mm, t_d + settle)
    if with_drift_diagnostics:
        diag.update(drift_diagnostics(tt, mm, *args, settle=settle, plain=est))
    return HoldWithIntervals(est, intervals, noise, model, alternates, diag)


def drift_diagnostics(t: np.ndarray, m: np.ndarray, geometry: ClampGeometry, theta_1: float,
                      theta_d: float, omega: float, t_d: float, settle: float = 0.0,
                      plain: HoldEstimate | None = None) -> dict[str, float]:
    """How much a linear drift fitted with the hold's exponential moves g1 and tau1:
    ``drift_log_g1`` and ``drift_log_tau1``, the log of the plain fit's value over the
    drift fit's (:func:`estimators.fit_hold_relaxation`), held within +-1; 0 where either fit
    fails.

    Why: a compliant contact that creeps lengthens the held moment's decay and the drift
    fit takes part of that back, so the two fits' disagreement says, per trace, how far the
    plain fit was pulled; a calibration (:mod:`estimators.calibration`) learns how much of it
    to undo.  ``plain``: the plain estimate already made on these arguments, so that only
    the drift fit is run.
    """
    args = (geometry, theta_1, theta_d, omega, t_d)
    try:
        if plain is None:
            plain = estimate_from_hold(t, m, *args, settle=settle)
        with_drift = estimate_from_hold(t, m, *args, settle=settle, drift=True,
                                        plain=plain.fit)
    except (EstimationError, ArithmeticError):
        return dict.fromkeys(DRIFT_DIAGNOSTICS, 0.0)
    out = {}
    for key, name in zip(DRIFT_DIAGNOSTICS, ("g1", "tau1"), strict=True):
        a, b = getattr(plain, name), getattr(with_drift, name)
        ok = a > 0 and b > 0 and math.isfinite(a) and math.isfinite(b)
        out[key] = float(np.clip(math.log(a / b), -1.0, 1.0)) if ok else 0.0
    return out
