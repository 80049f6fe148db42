"""Estimate the SLS parameters ``K1, K2, B`` of a food from one clamp-and-hold fetch.

Inputs are sampled traces: time ``t`` (s), hinge angle ``theta`` (rad, 0 at the open pose and
growing while closing) and the moment ``M`` (N m, positive when the food pushes the half-spoon
open), plus the :class:`~estimators.sls.ClampGeometry`. The clamp velocity ``omega`` and hold
angle ``theta_d`` are read off ``theta(t)`` unless given; first contact ``theta_1`` is detected
from ``M``. The moment sensor is assumed to read 0 before contact (tare it first).

Two estimators return the same :class:`ViscoelasticEstimate`:

* :func:`estimate_three_step` -- the study's method: (1) ``K1`` from ``M_inf`` (eq. 7), with
  ``M_inf`` and ``K2/B`` from a ``curve_fit`` of eq. 6 to the hold; (2) ``K2`` from
  ``M_peak = M(t_d)`` through the exact clamp solution (``M(t_d)`` is affine in ``K2`` once
  ``K2/B`` is fixed, so it is solved in closed form), then ``B = K2 / (K2/B)``.
* :func:`estimate_full_fit` -- one ``least_squares`` fit of the exact forward model to the whole
  trace for ``log K1, log K2, log B`` and ``theta_1``, with 95 % intervals from the Jacobian
  (``cov = s^2 (J^T J)^-1``, Student-t quantile, mapped back from log space).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import OptimizeResult, curve_fit, least_squares, minimize_scalar
from scipy.stats import t as student_t

from estimators.errors import EstimationError, check_traces, instance, optional_real, real
from estimators.sls import (
    ClampGeometry,
    SLSParams,
    moment_components,
    moment_trace,
    steady_moment,
)

__all__ = [
    "ClampKinematics",
    "ContactDetection",
    "HoldEstimate",
    "HoldFit",
    "ViscoelasticEstimate",
    "detect_contact",
    "estimate_from_hold",
    "estimate_full_fit",
    "estimate_three_step",
    "fit_hold_relaxation",
    "infer_kinematics",
]

_MIN_SAMPLES = 20
_MIN_HOLD_SAMPLES = 10
_PLATEAU_REL_TOL = 1e-3  # hold-plateau tolerance, fraction of theta_d
_LOG_SPAN = 20.0  # full fit: log-parameters kept within e^+-20 of their start


@dataclass(frozen=True)
class ClampKinematics:
    """Clamp motion read from ``theta(t)``.

    Attributes:
        omega: clamping velocity, rad/s.
        theta_d: hold angle, rad.
        t_start: time the ramp leaves ``theta = 0``, s.
        t_d: time the ramp reaches ``theta_d`` (``t_start + theta_d / omega``), s.
        theta_noise: robust estimate of the angle noise (sd), rad.
    """

    omega: float
    theta_d: float
    t_start: float
    t_d: float
    theta_noise: float


@dataclass(frozen=True)
class ContactDetection:
    """First contact detected on the moment trace.

    Attributes:
        theta_1: contact angle, rad.
        t_1: contact time, s.
        threshold: moment threshold used, N m.
        noise: robust sd of the moment noise, N m.
        n_rise: number of rise samples extrapolated back to ``M = 0``.
    """

    theta_1: float
    t_1: float
    threshold: float
    noise: float
    n_rise: int


@dataclass(frozen=True)
class HoldFit:
    """Fit of eq. 6, ``M = M_inf + A exp(-lam (t - t_d))``, to the hold.

    Attributes:
        M_inf: relaxed moment, N m.
        A: relaxing part ``M(t_d) - M_inf``, N m.
        lam: rate ``K2 / B``, 1/s.
        cov: 3x3 covariance of ``(M_inf, A, lam)``.
        r2: coefficient of determination on the hold samples.
        duration: hold length used, s.
        relaxes: whether a relaxation is resolved above the noise.
        drift: slope ``c`` of a linear drift ``+ c (t - t_d)`` fitted with the exponential
            (``fit_hold_relaxation(..., drift=True)``), N m/s; 0 where none was fitted.
            ``cov`` is then the marginal covariance of ``(M_inf, A, lam)``.
    """

    M_inf: float
    A: float
    lam: float
    cov: NDArray[np.float64]
    r2: float
    duration: float
    relaxes: bool
    drift: float = 0.0

    def model(self, s: NDArray[np.float64]) -> NDArray[np.float64]:
        """The fitted moment at ``s = t - t_d`` (s), N m."""
        return self.M_inf + self.A * np.exp(-self.lam * s) + self.drift * s


@dataclass
class ViscoelasticEstimate:
    """SLS parameters estimated from one fetch.

    Attributes:
        K1, K2: springs, N/m. B: dashpot, N s/m.
        g1: Prony weight ``K2/(K1+K2)``. tau1: Prony time ``B/K2``, s.
        theta_1: first-contact angle, rad. M_peak: ``M(t_d)``, N m. M_inf: relaxed moment, N m.
        t_d: time the clamp reaches ``theta_d``, s. omega: rad/s. theta_d: rad.
        intervals: 95 % intervals, name -> (low, high), same units as the value.
        r2_clamp, r2_hold: coefficients of determination of the model per phase.
        reliable: False when the numbers should not be trusted (see ``warnings``).
        warnings: human-readable reasons.
        method: ``"three_step"`` or ``"full_fit"``.
    """

    K1: float
    K2: float
    B: float
    g1: float
    tau1: float
    theta_1: float
    M_peak: float
    M_inf: float
    t_d: float
    omega: float
    theta_d: float
    intervals: dict[str, tuple[float, float]] = field(default_factory=dict)
    r2_clamp: float = math.nan
    r2_hold: float = math.nan
    reliable: bool = True
    warnings: list[str] = field(default_factory=list)
    method: str = ""

    def params(self) -> SLSParams:
        """The estimate as :class:`~estimators.sls.SLSParams` (raises if not identified)."""
        return SLSParams(self.K1, self.K2, self.B)


# --------------------------------------------------------------------------------------------
# helpers


def _robust_sd(x: NDArray[np.float64]) -> float:
    """Robust sd of white noise from second differences (MAD / sqrt 6), blind to smooth trends."""
    if x.size < 4:
        return 0.0
    d2 = np.diff(x, 2)
    return float(1.4826 * np.median(np.abs(d2 - np.median(d2))) / math.sqrt(6.0))


def _safe_exp(x: float) -> float:
    """``exp(x)`` clipped to the float range (no OverflowError on wild fits)."""
    return math.exp(min(max(float(x), -700.0), 700.0))


def _r2(y: NDArray[np.float64], yhat: NDArray[np.float64]) -> float:
    if y.size < 2:
        return math.nan
    ss_tot = float(np.sum((y - y.mean()) ** 2))
    ss_res = float(np.sum((y - yhat) ** 2))
    return 1.0 - ss_res / ss_tot if ss_tot > 0.0 else math.nan


def _validate(
    t: ArrayLike, theta: ArrayLike, M: ArrayLike, geometry: object
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    instance("geometry", geometry, ClampGeometry, "a ClampGeometry (L, theta_0)")
    tt, tr = check_traces(t, min_samples=_MIN_SAMPLES, theta=theta, M=M)
    return tt, tr["theta"], tr["M"]


# --------------------------------------------------------------------------------------------
# phase detection


def infer_kinematics(t: ArrayLike, theta: ArrayLike, omega: float | None = None,
                     theta_d: float | None = None) -> ClampKinematics:
    """Read the clamp velocity, hold angle and timing off ``theta(t)``.

    Args:
        t: times, s (strictly increasing).
        theta: hinge angle, rad (0 open, growing while closing).
        omega: clamping velocity (rad/s) if known; else the slope of a line fit to the ramp
            samples between 10 % and 90 % of ``theta_d``.
        theta_d: hold angle (rad) if known; else the median of the plateau samples.

    Raises:
        EstimationError: bad traces, ``theta`` never grows, no hold (``theta`` never plateaus),
            or too few ramp samples to read ``omega``.
    """
    omega, theta_d = optional_real("omega", omega), optional_real("theta_d", theta_d)
    tt, tr = check_traces(t, min_samples=_MIN_SAMPLES, theta=theta)
    th = tr["theta"]
    # Largest angle, robust to single-sample glitches: the max of a 5-sample running median.
    if th.size >= 5:
        th_max = float(np.max(np.median(np.lib.stride_tricks.sliding_window_view(th, 5), axis=1)))
    else:
        th_max = float(th.max())
    if th_max <= 0.0:
        raise EstimationError(
            f"theta never grows (max theta = {th_max!r} rad); expected a closing clamp"
        )
    # Angle noise from second differences (a ramp and a plateau both have zero 2nd difference).
    d2 = np.diff(th, 2)
    th_noise = float(1.4826 * np.median(np.abs(d2)) / math.sqrt(6.0))
    # Plateau tolerance: a measured angle sags under load (a servo holding a squeezed food
    # gives ~1e-5 rad at theta_d ~ 0.02 rad) and may show single-sample glitches, so allow
    # 0.1 % of theta_d (or 5 noise sd) and accept up to 10 % of stray samples in the hold.
    tol = max(_PLATEAU_REL_TOL * th_max, 5.0 * th_noise, 1e-12)
    if theta_d is None:
        plateau = th >= th_max - 2.0 * tol
        theta_d = float(np.median(th[plateau]))
    elif not (np.isfinite(theta_d) and theta_d > 0.0):
        raise EstimationError(f"theta_d must be finite and > 0 rad, got {theta_d!r}")
    on_plateau = np.abs(th - theta_d) <= tol
    # The hold: the samples after the last one well below the plateau (the end of the ramp), if
    # at least 90 % of them are on it (an angle that keeps creeping is no hold).
    below = np.flatnonzero(th < theta_d - 10.0 * tol)
    i_hold = int(below[-1]) + 1 if below.size else 0
    n_hold = th.size - i_hold
    frac_on = float(on_plateau[i_hold:].mean()) if n_hold else 0.0
    if n_hold < _MIN_HOLD_SAMPLES or frac_on < 0.9 or not on_plateau[-3:].all():
        n_final = int(np.argmin(on_plateau[::-1])) if not on_plateau.all() else th.size
        raise EstimationError(
            f"no hold phase: theta never plateaus (only {n_final} final samples within "
            f"{tol:.3g} rad of theta_d={theta_d:.6g} rad; need >= {_MIN_HOLD_SAMPLES})"
        )
    ramp = (th > 0.1 * theta_d) & (th < 0.9 * theta_d)
    n_ramp = int(ramp.sum())
    if omega is None:
        if n_ramp < 2:
            raise EstimationError(
                f"cannot infer omega: only {n_ramp} ramp sample(s) between 10 % and 90 % of "
                f"theta_d; pass omega"
            )
        slope, icpt = np.polyfit(tt[ramp], th[ramp], 1)
        omega = float(slope)
        if not omega > 0.0:
            raise EstimationError(f"inferred omega={omega!r} rad/s is not > 0")
        t_start = float(-icpt / omega)
    else:
        if not (np.isfinite(omega) and omega > 0.0):
            raise EstimationError(f"omega must be finite and > 0 rad/s, got {omega!r}")
        if n_ramp >= 1:
            t_start = float(np.mean(tt[ramp] - th[ramp] / omega))
        else:
            t_start = float(tt[i_hold] - theta_d / omega)
    t_d = t_start + theta_d / omega
    return ClampKinematics(float(omega), float(theta_d), t_start, float(t_d), th_noise)


def detect_contact(
    t: ArrayLike, M: ArrayLike, kin: ClampKinematics, threshold: float | None = None
) -> ContactDetection:
    """Detect first contact ``theta_1`` from the rise of the moment.

    The moment noise ``sigma`` is estimated robustly from the hold; the first of three
    consecutive samples above ``threshold`` (default ``max(6 sigma, 1 % of max M)``) marks the
    rise, and a polynomial (degree <= 3, fewer for few samples) fitted to the rise up to 60 % of
    the peak is extrapolated back to ``M = 0``, giving ``t_1`` to a fraction of a sample.

    Raises:
        EstimationError: if the moment never rises above the noise (no contact) or first rises
            only after the clamp has stopped, or a ``threshold`` that is not a real number.
    """
    threshold = optional_real("threshold", threshold)
    instance("kin", kin, ClampKinematics, "a ClampKinematics (infer_kinematics)")
    tt, traces = check_traces(t, min_samples=3, M=M)
    m = traces["M"]
    hold = tt > kin.t_d
    sigma = _robust_sd(m[hold]) if hold.sum() >= 3 else _robust_sd(m)
    clamp_and_hold = tt >= kin.t_start
    m_max = float(m[clamp_and_hold].max()) if clamp_and_hold.any() else float(m.max())
    if not (m_max > 6.0 * sigma and m_max > 0.0):
        raise EstimationError(
            f"no contact: the moment never rises above the noise (max M = {m_max:.3g} N m, "
            f"noise sd = {sigma:.3g} N m)"
        )
    thr = max(6.0 * sigma, 0.01 * m_max) if threshold is None else float(threshold)
    above = m > thr
    run = above[:-2] & above[1:-1] & above[2:]
    idx = np.flatnonzero(run & clamp_and_hold[:-2])
    if idx.size == 0:
        raise EstimationError(
            f"no contact: the moment never stays above the threshold {thr:.3g} N m "
            f"(max M = {m_max:.3g} N m, noise sd = {sigma:.3g} N m)"
        )
    k = int(idx[0])
    dt = float(np.median(np.diff(tt)))
    if tt[k] > kin.t_d + 2.0 * dt:
        raise EstimationError(
            f"no contact during the clamp: the moment first exceeds {thr:.3g} N m at "
            f"t={tt[k]:.6g} s, after the clamp stopped at t_d={kin.t_d:.6g} s"
        )
    # Rise samples: from k while M < 60 % of the peak (at least 4 if the clamp allows).
    j = k
    while j < tt.size and tt[j] <= kin.t_d + 1e-9 * dt and (m[j] < 0.6 * m_max or j - k < 4):
        j += 1
    sel = slice(k, max(j, k + 2))
    tr, mr = tt[sel], m[sel]
    n = tr.size
    # Noise-free traces: a cubic gives t_1 to ~1e-8 rad. Noisy ones: a straight line, since the
    # variance of a polynomial's extrapolation grows fast with its degree (checked: at 1 % noise
    # a line beats a quadratic by 2-3x on K1).
    deg = 3 if n >= 12 else (2 if n >= 4 else 1)
    if sigma > 1e-4 * m_max:
        deg = 1
    tc = tr[0]
    coef = np.polyfit(tr - tc, mr, deg)
    # Root of the fitted rise nearest to (and not after) the first crossing.
    roots = np.roots(coef)
    lo_t = min(kin.t_start, tt[max(k - 3, 0)]) - tc
    cand = [
        r.real for r in roots if abs(r.imag) < 1e-9 * max(1.0, abs(r.real)) and lo_t <= r.real <= 0
    ]
    if cand:
        t1 = tc + max(cand)
    else:  # fall back to a straight line through the rise samples
        slope, icpt = np.polyfit(tr - tc, mr, 1)
        t1 = tc - icpt / slope if slope > 0 else tc
    theta_1 = float(np.clip(kin.omega * (t1 - kin.t_start), 0.0, kin.theta_d))
    return ContactDetection(theta_1, float(t1), float(thr), float(sigma), int(n))


# --------------------------------------------------------------------------------------------
# eq. 6 fit


def _exp_model(s: NDArray[np.float64], m_inf: float, a: float, lam: float):
    return m_inf + a * np.exp(-lam * s)


def _exp_jac(s: NDArray[np.float64], m_inf: float, a: float, lam: float, columns: int = 3):
    """eq. 6's Jacobian in its three parameters, in an (n, ``columns``) array whose columns
    past the third the caller fills (the hot loop of every decay fit: one array, no
    stacking)."""
    e = np.exp(-lam * s)
    jac = np.empty((s.size, columns))
    jac[:, 0] = 1.0
    jac[:, 1] = e
    jac[:, 2] = -a * s * e
    return jac


def _exp_drift_model(s: NDArray[np.float64], m_inf: float, a: float, lam: float, c: float):
    return m_inf + a * np.exp(-lam * s) + c * s


def _exp_drift_jac(s: NDArray[np.float64], m_inf: float, a: float, lam: float, c: float):
    jac = _exp_jac(s, m_inf, a, lam, columns=4)
    jac[:, 3] = s
    return jac


def _trf(tol: float) -> dict[str, Any]:
    """scipy's bounded trust-region solver as the full fit uses it: Jacobian-scaled steps,
    ``tol`` on x, the cost and the gradient, at most 200 evaluations."""
    return {"method": "trf", "x_scale": "jac", "xtol": tol, "ftol": tol, "gtol": tol,
            "max_nfev": 200}


# The tolerance of the decay fits (x, cost and gradient).
_DECAY_TOL = 1e-14

# The least decay over the hold, rate * duration, at which _fit_decay keeps the unbounded
# Levenberg-Marquardt fit (a hold counts as relaxing from 0.02, HoldFit.relaxes).
LM_MIN_DECAY = 1e-3
LM_MAX_EVALUATIONS = 100


def _fit_decay(s: NDArray[np.float64], y: NDArray[np.float64], p0: tuple[float, float, float]
               ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Least squares of eq. 6, ``M_inf + A exp(-rate s)`` with rate >= 0, from ``p0``:
    MINPACK's Levenberg-Marquardt (:func:`_lm_decay`) where it resolves a decay, else
    the search over the rate (:func:`_fit_decay_projected`), which finds the bounded
    minimum where LM drives the rate negative, fails, or stops in the degenerate valley of
    a vanishing rate and a huge amplitude (a nearly straight hold).

    Raises:
        RuntimeError: neither finds a decay; ValueError (numpy's ``LinAlgError``): the
            search's linear least squares does not converge.
    """
    fit = _lm_decay(_exp_model, _exp_jac, s, y, p0)
    return fit if fit is not None else _fit_decay_projected(s, y, line=False)


def _lm_decay(model: Any, jac: Any, s: NDArray[np.float64], y: NDArray[np.float64],
              p0: tuple[float, ...]
              ) -> tuple[NDArray[np.float64], NDArray[np.float64]] | None:
    """The unbounded Levenberg-Marquardt ``curve_fit`` of a decay ``model`` (third
    parameter the rate), or None where it fails or its rate does not resolve a decay over
    the hold (``rate * duration <= LM_MIN_DECAY``).

    Why first: an interior minimum of the unbounded problem is the bounded one's too, and on
    the probes' holds it takes 1-2 ms (5-65 evaluations) where the search over the rate
    (:func:`_fit_decay_projected`) takes ~3 ms, agreeing with it to ~1e-8 in the rate.  At
    most ``LM_MAX_EVALUATIONS``: a fit that needs more is in the valley of a vanishing rate,
    which the search crosses faster.
    """
    try:
        popt, pcov = curve_fit(model, s, y, p0=p0, jac=jac, method="lm", xtol=_DECAY_TOL,
                               ftol=_DECAY_TOL, gtol=0.0, maxfev=LM_MAX_EVALUATIONS)
    except (RuntimeError, ValueError):
        return None
    if (popt[2] * s[-1] > LM_MIN_DECAY and np.all(np.isfinite(popt))
            and np.all(np.isfinite(pcov))):
        return popt, pcov
    return None


# The rates, times the hold's duration, over which _fit_decay_projected searches: from a
# decay of 0.1 % over the hold (nearly a line) to one over within 0.1 % of it (a step).
_PROJECTED_RATES = (1e-3, 1e3)
_PROJECTED_GRID = 61


def _fit_decay_projected(s: NDArray[np.float64], y: NDArray[np.float64], line: bool
                         ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Least squares of eq. 6, ``M_inf + A exp(-rate s)`` with rate >= 0, plus a line
    ``c s`` where ``line``, by variable projection: for a fixed rate the model is linear in
    the others, so the fit is a one-dimensional search of the residual over the rate (a
    log-spaced grid, then ``scipy.optimize.minimize_scalar`` between the best point's
    neighbours).

    Why: where a slow decay nearly coincides with a line, or with a constant, the problem
    has a long, flat valley (a vanishing rate, a huge amplitude) that Levenberg-Marquardt
    and a bounded trust-region solver may walk for their whole budget without converging
    (~30-80 ms a fit); the search over the rate alone takes ~3 ms and finds the minimum, or
    says there is none inside the rates (the best grid point at either end: the decay is
    not separable from the line or constant, or from a step).  Returns ``(M_inf, A, rate)``
    (and ``c``) and their covariance (``s^2 (J^T J)^-1``, as ``curve_fit``).

    Raises:
        RuntimeError: no minimum inside the rates, or a singular Jacobian at the minimum;
        ValueError (numpy's ``LinAlgError``): a linear least squares does not converge.
    """
    n_params = 4 if line else 3
    duration = float(s[-1])
    if not (duration > 0.0 and s.size > n_params):
        raise RuntimeError(f"a decay needs a hold of more than {n_params} samples")
    rates = np.geomspace(_PROJECTED_RATES[0] / duration, _PROJECTED_RATES[1] / duration,
                         _PROJECTED_GRID)
    rss = np.array([_projection(s, y, r, line)[0] for r in rates])
    k = int(np.argmin(rss))
    if k in (0, rates.size - 1):
        raise RuntimeError("the decay is not separable: the least residual is at the edge "
                           f"of the rates searched, {rates[k]:.3g} 1/s")
    res = minimize_scalar(lambda u: _projection(s, y, math.exp(u), line)[0],
                          bounds=(math.log(rates[k - 1]), math.log(rates[k + 1])),
                          method="bounded", options={"xatol": 1e-9})
    rate = math.exp(float(res.x))
    rss_min, beta = _projection(s, y, rate, line)
    popt = np.array([beta[0], beta[1], rate, *beta[2:]])
    jac = (_exp_drift_jac if line else _exp_jac)(s, *popt)
    try:
        pcov = np.linalg.inv(jac.T @ jac) * rss_min / (s.size - n_params)
    except np.linalg.LinAlgError as exc:
        raise RuntimeError("singular Jacobian at the decay's minimum") from exc
    return popt, pcov


def _projection(s: NDArray[np.float64], y: NDArray[np.float64], rate: float, line: bool
                ) -> tuple[float, NDArray[np.float64]]:
    """The residual sum of squares of the best ``M_inf + A exp(-rate s)`` (``+ c s`` where
    ``line``) at ``rate``, and that ``(M_inf, A)`` (``, c``)."""
    basis = np.empty((s.size, 3 if line else 2))
    basis[:, 0] = 1.0
    basis[:, 1] = np.exp(-rate * s)
    if line:
        basis[:, 2] = s
    beta, *_ = np.linalg.lstsq(basis, y, rcond=None)
    r = y - basis @ beta
    return float(r @ r), beta


def fit_hold_relaxation(t: ArrayLike, M: ArrayLike, t_d: float, drift: bool = False,
                        plain: HoldFit | None = None) -> HoldFit:
    """Fit eq. 6 to the hold samples ``t > t_d`` with ``scipy.optimize.curve_fit``
    (:func:`_fit_decay`).

    Start values come from the linear integral form ``M(t) - M(t_a) = -lam int M + lam M_inf (t -
    t_a)`` (exact for an exponential, robust to noise). ``relaxes`` is False when the fitted decay
    ``A`` is not resolved (``A <= 4 se(A)`` or ``A <= 1e-3 M(t_d)``), the moment grows in the hold,
    or the fit does not converge.

    With ``drift``, eq. 6 plus a straight line ``c (t - t_d)`` is fitted, started from the
    plain fit.  Why: a clamp's contact creeps (the blades sink into a stiff piece, the pads and
    drive give) and its held moment then falls slowly even without viscoelasticity; a single
    exponential absorbs that fall into a longer decay.  Only a hold several ``tau1`` long
    separates the two: on a shorter one the line trades off against the decay.  (On the
    validation harness's tuning foods, a 19.75 s hold, it cut tau1's median error from 6.1 to
    4.6 % but raised g1's from 2.3 to 3.7 %; the probes use the plain fit, and the two fits'
    disagreement as a calibration input, :func:`estimators.uncertainty.drift_diagnostics`.)

    ``plain``: the plain fit already made on these samples (``drift`` False, converged), so
    that with ``drift`` only the refit with the line runs; the result is the same.

    Raises:
        EstimationError: fewer than 10 hold samples, a ``t_d`` that is not a finite number,
            ``drift`` not a bool or ``plain`` not a :class:`HoldFit` (or None).
    """
    t_d = real("t_d", t_d)
    if not math.isfinite(t_d):
        raise EstimationError(f"t_d must be a finite time in s, got {t_d!r}")
    instance("drift", drift, bool | np.bool_, "True or False")
    if plain is not None:
        instance("plain", plain, HoldFit, "a HoldFit (fit_hold_relaxation) or None")
    tt, traces = check_traces(t, min_samples=1, M=M)
    m = traces["M"]
    hold = tt > t_d
    s, y = tt[hold] - t_d, m[hold]
    if s.size < _MIN_HOLD_SAMPLES:
        raise EstimationError(
            f"no hold phase: only {s.size} samples after t_d={t_d:.6g} s; need >= "
            f"{_MIN_HOLD_SAMPLES}"
        )
    duration = float(s[-1])
    if drift and plain is not None and plain.drift == 0.0 and np.all(np.isfinite(plain.cov)):
        popt, pcov = np.array([plain.M_inf, plain.A, plain.lam]), plain.cov
        return _hold_fit(s, y, duration, *_add_drift(s, y, popt, pcov), converged=True)
    # Integral-form start values.
    cum = np.concatenate(([0.0], np.cumsum(0.5 * (y[1:] + y[:-1]) * np.diff(s))))
    X = np.column_stack((-cum, s - s[0]))
    (lam0, lm0), *_ = np.linalg.lstsq(X, y - y[0], rcond=None)
    lam0 = float(lam0)
    if not (lam0 > 0.0 and np.isfinite(lam0)):
        lam0 = 3.0 / max(duration, 1e-9)
    m_inf0 = float(lm0 / lam0) if lam0 > 0 else float(y[-1])
    if not np.isfinite(m_inf0):
        m_inf0 = float(y[-1])
    a0 = float(y[0] - m_inf0) * _safe_exp(lam0 * s[0])
    p0 = (m_inf0, a0, lam0)
    try:
        popt, pcov = _fit_decay(s, y, p0)
        converged = bool(np.all(np.isfinite(popt)) and np.all(np.isfinite(pcov)))
    except (RuntimeError, ValueError):
        popt, pcov, converged = np.asarray(p0), np.full((3, 3), np.inf), False
    c = 0.0
    if drift and converged:
        popt, pcov, c = _add_drift(s, y, popt, pcov)
    return _hold_fit(s, y, duration, popt, pcov, c, converged)


def _hold_fit(s: NDArray[np.float64], y: NDArray[np.float64], duration: float,
              popt: NDArray[np.float64], pcov: NDArray[np.float64], c: float,
              converged: bool) -> HoldFit:
    """The :class:`HoldFit` of fitted ``(M_inf, A, lam)``, their covariance and drift ``c``
    on the hold samples ``(s, y)``: its R^2 and whether it resolves a relaxation."""
    m_inf, a, lam = (float(v) for v in popt)
    r2 = _r2(y, _exp_drift_model(s, m_inf, a, lam, c))
    se_a = float(np.sqrt(pcov[1, 1])) if np.isfinite(pcov[1, 1]) else np.inf
    m_d = m_inf + a
    relaxes = bool(
        converged
        and a > 0.0
        and lam > 0.0
        and a > 4.0 * se_a
        and a > 1e-3 * abs(m_d)
        and lam * duration > 0.02
    )
    return HoldFit(m_inf, a, lam, np.asarray(pcov, dtype=np.float64), r2, duration, relaxes, c)


def _add_drift(s: NDArray[np.float64], y: NDArray[np.float64], popt: NDArray[np.float64],
               pcov: NDArray[np.float64]
               ) -> tuple[NDArray[np.float64], NDArray[np.float64], float]:
    """Refit eq. 6 plus a linear drift from the plain fit ``popt`` (Levenberg-Marquardt,
    else :func:`_fit_decay_projected`); the plain fit (and no drift) where both fail.  Returns
    ``(M_inf, A, lam)``, their marginal covariance and the drift's slope."""
    fit = _lm_decay(_exp_drift_model, _exp_drift_jac, s, y, (*popt, 0.0))
    if fit is None:
        try:
            fit = _fit_decay_projected(s, y, line=True)
        except (RuntimeError, ValueError):  # ValueError: numpy's LinAlgError
            return popt, pcov, 0.0
    p4, c4 = fit
    if not (np.all(np.isfinite(p4)) and np.all(np.isfinite(c4))):
        return popt, pcov, 0.0
    return p4[:3], c4[:3, :3], float(p4[3])


# --------------------------------------------------------------------------------------------
# three-step method


def _k2_from_peak(
    m_peak: float,
    K1: float,
    lam: float,
    geometry: ClampGeometry,
    theta_1: float,
    kin: ClampKinematics,
) -> float:
    """Step 3: the ``K2`` whose clamp solution gives ``M(t_d) = m_peak`` (``B = K2 / lam``).

    With ``lam`` fixed the exact moment is ``K1 S + K2 V``
    (:func:`estimators.sls.moment_components`), so ``K2 = (m_peak - K1 S(t_d)) / V(t_d)``
    solves it in closed form."""
    S, V = moment_components(np.array([kin.t_d]), geometry, theta_1, kin.theta_d, kin.omega,
                             lam, kin.t_start)
    elastic = K1 * float(S[0])
    if elastic >= m_peak:
        raise EstimationError(
            f"M_peak={m_peak:.6g} N m does not exceed the relaxed moment of K1 alone "
            f"({elastic:.6g} N m): the moment never relaxes, K2 is not identifiable"
        )
    v_d = float(V[0])
    if not (v_d > 0.0 and math.isfinite(v_d)):
        raise EstimationError(
            f"the Maxwell arm carries no moment at t_d (V={v_d!r} m^2, rate {lam!r} 1/s): "
            "K2 is not identifiable"
        )
    return (m_peak - elastic) / v_d


def _three_step_core(
    hf: HoldFit,
    geometry: ClampGeometry,
    theta_1: float,
    kin: ClampKinematics,
    m_inf: float | None = None,
    a: float | None = None,
    lam: float | None = None,
) -> tuple[float, float, float]:
    m_inf = hf.M_inf if m_inf is None else m_inf
    a = hf.A if a is None else a
    lam = hf.lam if lam is None else lam
    unit = steady_moment(1.0, geometry, theta_1, kin.theta_d)  # eq. 7: M_inf per unit K1
    if unit <= 0.0:
        raise EstimationError(
            f"theta_1={theta_1:.6g} rad is not below theta_d={kin.theta_d:.6g} rad: no compression"
        )
    K1 = m_inf / unit
    if not K1 > 0.0:
        raise EstimationError(f"relaxed moment M_inf={m_inf:.6g} N m gives K1 <= 0")
    K2 = _k2_from_peak(m_inf + a, K1, lam, geometry, theta_1, kin)
    return K1, K2, K2 / lam


def estimate_three_step(t: ArrayLike, theta: ArrayLike, M: ArrayLike, geometry: ClampGeometry,
                        omega: float | None = None,
                        theta_d: float | None = None) -> ViscoelasticEstimate:
    """The study's three-step estimate of ``K1, K2, B`` (see module docstring).

    Args:
        t: times, s. theta: hinge angle, rad. M: moment, N m.
        geometry: clamp geometry (``L`` m, ``theta_0`` rad).
        omega: clamping velocity (rad/s) if known. theta_d: hold angle (rad) if known.

    Returns:
        A :class:`ViscoelasticEstimate`. Intervals propagate the eq. 6 fit's covariance (of
        ``M_inf``, ``A``, ``K2/B``) by the delta method; the uncertainty of the detected
        ``theta_1`` is not included. If the moment never relaxes, ``K2``, ``B`` (and ``g1``,
        ``tau1``) are NaN and ``reliable`` is False.

    Raises:
        EstimationError: bad traces, no hold, no contact.
    """
    tt, th, m = _validate(t, theta, M, geometry)
    kin, contact, hf = _clamp_phases(tt, th, m, omega, theta_d)
    return _three_step_from_parts(tt, m, geometry, kin, contact, hf)


def _clamp_phases(
    tt: NDArray[np.float64],
    th: NDArray[np.float64],
    m: NDArray[np.float64],
    omega: float | None,
    theta_d: float | None,
) -> _ClampPhases:
    """The clamp's kinematics, first contact and eq. 6 hold fit: both estimators start here."""
    kin = infer_kinematics(tt, th, omega, theta_d)
    contact = detect_contact(tt, m, kin)
    return _ClampPhases(kin, contact, fit_hold_relaxation(tt, m, kin.t_d))


class _ClampPhases(NamedTuple):
    """What the phase detection read off one clamp-and-hold trace."""

    kin: ClampKinematics
    contact: ContactDetection
    hf: HoldFit


@dataclass(frozen=True)
class HoldEstimate:
    """SLS parameters from the hold alone (see :func:`estimate_from_hold`).

    Attributes:
        K1, K2: springs, N/m. B: dashpot, N s/m. g1: Prony weight ``K2/(K1+K2)``.
        tau1: Prony time ``B/K2`` (the hold's own decay time), s.
        fit: the eq. 6 fit to the hold past ``settle`` it comes from.
    """

    K1: float
    K2: float
    B: float
    g1: float
    tau1: float
    fit: HoldFit


def estimate_from_hold(t: ArrayLike, M: ArrayLike, geometry: ClampGeometry, theta_1: float,
                       theta_d: float, omega: float, t_d: float,
                       settle: float = 0.0, drift: bool = False,
                       plain: HoldFit | None = None) -> HoldEstimate:
    """``K1, K2, B`` (and ``g1, tau1``) from the hold alone, past a settling time.

    Eq. 6 is fitted to the samples after ``t_d + settle``: its rate is ``1 / tau1`` for any SLS
    held at a constant angle.  Its relaxing part is carried back to ``t_d`` at that rate, and the
    study's steps 1 and 3 (eq. 7 for ``K1``, the exact clamp solution for ``K2``) turn ``M_inf``
    and ``M(t_d)`` into the springs; that divides out the relaxation during the ramp, which a
    bare ``g1 = A / (M_inf + A)`` would miss (by ~``T / 2 tau1`` for a ramp of ``T`` s).  Only
    the contact angle ``theta_1`` comes from outside the hold (a clamp fit's or the detected
    one).

    Why: where the clamp rise is not the SLS's (a piece that rocks or chatters as the blades
    close, the moment still rising after ``t_d`` while it settles), a fit that weights the
    clamp misplaces ``M(t_d)`` and the decay; the hold past ``settle`` follows eq. 6 for any SLS.

    Args:
        t: times, s. M: moment, N m (the hold samples are those after ``t_d + settle``).
        geometry: clamp geometry. theta_1: contact angle, rad. theta_d: hold angle, rad.
        omega: clamping velocity, rad/s. t_d: time the clamp reaches ``theta_d``, s.
        settle: start of the hold left out, s (>= 0).
        drift: fit a linear drift with the exponential (:func:`fit_hold_relaxation`).
        plain: with ``drift``, the plain hold fit already made on the same arguments (its
            ``fit``), so that only the refit with the line runs.

    Raises:
        EstimationError: bad traces or settings, too short a hold, or a hold that does not
            relax (``fit_hold_relaxation``'s ``relaxes`` is False).
    """
    theta_1, theta_d, omega, t_d, settle = (
        real(name, v) for name, v in (("theta_1", theta_1), ("theta_d", theta_d),
                                      ("omega", omega), ("t_d", t_d), ("settle", settle)))
    instance("geometry", geometry, ClampGeometry, "a ClampGeometry (L, theta_0)")
    tt, traces = check_traces(t, M=M)
    m = traces["M"]
    for name, value in (("theta_d", theta_d), ("omega", omega)):
        if not (math.isfinite(value) and value > 0.0):
            raise EstimationError(f"{name} must be finite and > 0, got {value!r}")
    if not math.isfinite(t_d):
        raise EstimationError(f"t_d must be finite, got {t_d!r}")
    if not (math.isfinite(settle) and settle >= 0.0):
        raise EstimationError(f"settle must be finite and >= 0 s, got {settle!r}")
    if not 0.0 <= theta_1 < theta_d:
        raise EstimationError(f"theta_1={theta_1!r} rad must be in [0, theta_d={theta_d!r})")
    hf = fit_hold_relaxation(tt, m, t_d + settle, drift=drift, plain=plain)
    if not hf.relaxes:
        raise EstimationError(
            "the hold does not relax above the noise: g1 and tau1 are not identified"
        )
    kin = ClampKinematics(
        omega=omega, theta_d=theta_d, t_start=t_d - theta_d / omega, t_d=t_d, theta_noise=0.0
    )
    a_d = hf.A * math.exp(hf.lam * settle)
    K1, K2, B = _three_step_core(hf, geometry, theta_1, kin, a=a_d)
    return HoldEstimate(K1=K1, K2=K2, B=B, g1=K2 / (K1 + K2), tau1=1.0 / hf.lam, fit=hf)


def _never_relaxes_estimate(tt: NDArray[np.float64], m: NDArray[np.float64],
                            geometry: ClampGeometry, kin: ClampKinematics, theta_1: float,
                            hf: HoldFit, method: str,
                            extra: list[str] | None = None) -> ViscoelasticEstimate:
    hold = tt > kin.t_d
    m_inf = float(np.mean(m[hold]))
    unit = steady_moment(1.0, geometry, theta_1, kin.theta_d)
    K1 = m_inf / unit if unit > 0 else math.nan
    warns = [
        f"the moment never relaxes in the hold (fitted decay A={hf.A:.3g} N m, "
        f"rate={hf.lam:.3g} 1/s over {hf.duration:.3g} s): K2 and B are not identifiable; "
        "K1 assumes a purely elastic food"
    ]
    warns += extra or []
    return ViscoelasticEstimate(
        K1=K1,
        K2=math.nan,
        B=math.nan,
        g1=math.nan,
        tau1=math.nan,
        theta_1=theta_1,
        M_peak=float(m[hold][0]),
        M_inf=m_inf,
        t_d=kin.t_d,
        omega=kin.omega,
        theta_d=kin.theta_d,
        r2_hold=hf.r2,
        reliable=False,
        warnings=warns,
        method=method,
    )


def _three_step_from_parts(tt: NDArray[np.float64], m: NDArray[np.float64], geometry: ClampGeometry,
                           kin: ClampKinematics, contact: ContactDetection,
                           hf: HoldFit) -> ViscoelasticEstimate:
    theta_1 = contact.theta_1
    if not hf.relaxes:
        return _never_relaxes_estimate(tt, m, geometry, kin, theta_1, hf, "three_step")
    warns: list[str] = []
    K1, K2, B = _three_step_core(hf, geometry, theta_1, kin)
    # Delta-method intervals from the hold-fit covariance.
    base = np.array([hf.M_inf, hf.A, hf.lam])
    vals = np.array([K1, K2, B])
    Jm = np.empty((3, 3))
    for i in range(3):
        h = 1e-6 * max(abs(base[i]), 1e-12)
        pp, pm = base.copy(), base.copy()
        pp[i] += h
        pm[i] -= h
        Jm[:, i] = (
            np.array(_three_step_core(hf, geometry, theta_1, kin, *pp))
            - np.array(_three_step_core(hf, geometry, theta_1, kin, *pm))
        ) / (2 * h)
    cov = Jm @ hf.cov @ Jm.T
    se = np.sqrt(np.clip(np.diag(cov), 0.0, np.inf))
    n_hold = int((tt > kin.t_d).sum())
    q = float(student_t.ppf(0.975, max(n_hold - 3, 1)))
    intervals = {
        name: (float(v - q * s), float(v + q * s))
        for name, v, s in zip(("K1", "K2", "B"), vals, se, strict=True)
    }
    tau1 = 1.0 / hf.lam
    se_tau = math.sqrt(hf.cov[2, 2]) / hf.lam**2 if np.isfinite(hf.cov[2, 2]) else math.inf
    intervals["tau1"] = (tau1 - q * se_tau, tau1 + q * se_tau)
    params = SLSParams(K1, K2, B)
    clamp = (tt > contact.t_1) & (tt <= kin.t_d)
    m_model = moment_trace(
        tt[clamp], params, geometry, theta_1, kin.theta_d, kin.omega, kin.t_start
    )
    r2_clamp = _r2(m[clamp], m_model)
    reliable = _reliability(hf, tau1, vals, se * q, warns, r2_clamp)
    if contact.n_rise < 3:
        warns.append(
            f"contact angle extrapolated from only {contact.n_rise} rise samples; "
            "theta_1 (and hence K1) is coarse"
        )
        reliable = False
    return ViscoelasticEstimate(
        K1=K1,
        K2=K2,
        B=B,
        g1=params.g1,
        tau1=tau1,
        theta_1=theta_1,
        M_peak=hf.M_inf + hf.A,
        M_inf=hf.M_inf,
        t_d=kin.t_d,
        omega=kin.omega,
        theta_d=kin.theta_d,
        intervals=intervals,
        r2_clamp=r2_clamp,
        r2_hold=hf.r2,
        reliable=reliable,
        warnings=warns,
        method="three_step",
    )


def _reliability(
    hf: HoldFit,
    tau1: float,
    vals: NDArray[np.float64],
    half_widths: NDArray[np.float64],
    warns: list[str],
    r2_clamp: float,
) -> bool:
    ok = True
    if hf.duration < tau1:
        warns.append(
            f"hold ({hf.duration:.3g} s) is shorter than tau1 ({tau1:.3g} s): M_inf and K1 are "
            "extrapolated"
        )
        ok = False
    for name, v, hw in zip(("K1", "K2", "B"), vals, half_widths, strict=True):
        if not (np.isfinite(hw) and hw < 0.5 * abs(v)):
            warns.append(f"{name} is poorly determined (95 % half-width {hw:.3g} vs {v:.3g})")
            ok = False
    if np.isfinite(r2_clamp) and r2_clamp < 0.9:
        warns.append(f"clamp-phase R^2 = {r2_clamp:.4f} < 0.9: the SLS model fits the clamp poorly")
        ok = False
    return ok


# --------------------------------------------------------------------------------------------
# full least-squares fit


def estimate_full_fit(
    t: ArrayLike,
    theta: ArrayLike,
    M: ArrayLike,
    geometry: ClampGeometry,
    omega: float | None = None,
    theta_d: float | None = None,
    fit_theta_1: bool = True,
    clamp_weight: float = 1.0,
    theta_1: float | None = None,
) -> ViscoelasticEstimate:
    """Fit the exact clamp+hold model to the whole trace at once (see module docstring).

    Parameters ``log K1, log K2, log B`` (each kept within ``e^+-20`` of its start, so a wild
    fit cannot overflow) and ``theta_1`` in ``[0, theta_d)`` when ``fit_theta_1`` are fitted by
    ``scipy.optimize.least_squares`` (TRF) to every sample, starting from the three-step
    estimate. 95 % intervals use ``s^2 (J^T J)^-1`` with a Student-t quantile, mapped back from
    log space; ``g1``/``tau1`` intervals by the delta method.

    Args:
        t: times, s. theta: hinge angle, rad. M: moment, N m.
        geometry: clamp geometry.
        omega, theta_d: clamp velocity (rad/s) and hold angle (rad) if known.
        fit_theta_1: also fit the contact angle (default); else keep the detected one.
        clamp_weight: weight of the clamp-phase residuals relative to the hold's (default 1,
            ordinary least squares). Below 1 it lets the hold, where eq. 6 is exact for any SLS,
            dominate when the clamp rise is not the SLS's (e.g. a contact area that grows).
        theta_1: a known first-contact angle, rad (e.g. where a depth camera sees the faces
            reach the piece's surface), used instead of the one detected on the trace and
            not fitted.  K1, K2 and B scale with ``1 / (sin theta_d - sin theta_1)`` and a
            gentle clamp squeezes a few per cent of the piece's width, so a known angle
            gives them where a soft or rocking first touch misleads the detection.

    Raises:
        EstimationError: bad traces, no hold, no contact, a non-finite model or a solver
            failure, or a given ``theta_1`` outside ``[0, theta_d)``.
    """
    tt, th, m = _validate(t, theta, M, geometry)
    _check_full_fit_options(fit_theta_1, clamp_weight)
    theta_1 = optional_real("theta_1", theta_1)
    phases = _with_known_contact(_clamp_phases(tt, th, m, omega, theta_d), theta_1)
    fit_theta_1 = fit_theta_1 and theta_1 is None
    kin, contact, hf = phases
    if not hf.relaxes:
        return _never_relaxes_estimate(tt, m, geometry, kin, contact.theta_1, hf, "full_fit")
    start = _full_fit_start(tt, m, geometry, phases)
    x0, lb, ub, theta_1_0 = _search_box(start, contact.theta_1, kin.theta_d, fit_theta_1)
    model = _clamp_hold_model(tt, geometry, kin, theta_1_0 if not fit_theta_1 else None)
    w = np.where(tt <= kin.t_d, math.sqrt(clamp_weight), 1.0)
    res = _least_squares_fit(model, w, m, x0, lb, ub)
    p = res.x
    k1, k2, b = (_safe_exp(v) for v in p[:3])
    th1 = float(p[3]) if fit_theta_1 else theta_1_0
    if not all(np.isfinite(v) and v > 0.0 for v in (k1, k2, b)):
        raise EstimationError(f"full fit diverged: K1={k1!r}, K2={k2!r}, B={b!r}")
    cov, dof = _fit_covariance(res, tt.size)
    params = SLSParams(k1, k2, b)
    intervals = _full_fit_intervals(p, cov, float(student_t.ppf(0.975, dof)), params, th1)
    g1, tau1 = params.to_prony()
    fitted = model(p)
    clamp = (tt > kin.t_start + th1 / kin.omega) & (tt <= kin.t_d)
    hold = tt > kin.t_d
    r2_clamp = _r2(m[clamp], fitted[clamp])
    reliable, warns = _full_fit_reliability(res, (lb, ub), cov, hf, tau1, intervals, r2_clamp)
    td = np.array([kin.t_d])
    m_peak = float(moment_trace(td, params, geometry, th1, kin.theta_d, kin.omega, kin.t_start)[0])
    return ViscoelasticEstimate(
        K1=k1,
        K2=k2,
        B=b,
        g1=g1,
        tau1=tau1,
        theta_1=th1,
        M_peak=m_peak,
        M_inf=steady_moment(params, geometry, th1, kin.theta_d),
        t_d=kin.t_d,
        omega=kin.omega,
        theta_d=kin.theta_d,
        intervals=intervals,
        r2_clamp=r2_clamp,
        r2_hold=_r2(m[hold], fitted[hold]),
        reliable=bool(reliable),
        warnings=warns,
        method="full_fit",
    )


def _with_known_contact(phases: _ClampPhases, theta_1: float | None) -> _ClampPhases:
    """``phases`` with the first contact at a known angle ``theta_1`` (where given)."""
    if theta_1 is None:
        return phases
    kin = phases.kin
    if not (math.isfinite(theta_1) and 0.0 <= theta_1 < kin.theta_d):
        raise EstimationError(f"theta_1={theta_1!r} rad must be in [0, theta_d={kin.theta_d!r})")
    contact = dataclasses.replace(phases.contact, theta_1=theta_1,
                                  t_1=kin.t_start + theta_1 / kin.omega)
    return phases._replace(contact=contact)


def _check_full_fit_options(fit_theta_1: object, clamp_weight: float) -> None:
    """Refuse a ``fit_theta_1`` that is not a bool and a ``clamp_weight`` that is not > 0."""
    if not isinstance(fit_theta_1, bool | np.bool_):
        raise EstimationError(f"fit_theta_1 must be True or False, got {fit_theta_1!r}")
    if not (np.isfinite(real("clamp_weight", clamp_weight)) and clamp_weight > 0.0):
        raise EstimationError(f"clamp_weight must be finite and > 0, got {clamp_weight!r}")


def _full_fit_start(
    tt: NDArray[np.float64], m: NDArray[np.float64], geometry: ClampGeometry, phases: _ClampPhases
) -> tuple[float, float, float]:
    """Start values ``K1, K2, B`` of the full fit: the three-step estimate where it gives
    positive numbers, else eq. 7's ``K1`` with ``K2 = K1`` and ``B`` from the hold's rate."""
    kin, contact, hf = phases
    K1_0 = K2_0 = B_0 = math.nan
    try:
        start = _three_step_from_parts(tt, m, geometry, kin, contact, hf)
        K1_0, K2_0, B_0 = start.K1, start.K2, start.B
    except (EstimationError, ArithmeticError, ValueError):
        pass
    if not all(np.isfinite(v) and v > 0.0 for v in (K1_0, K2_0, B_0)):
        K1_0 = max(hf.M_inf, 1e-12) / max(
            steady_moment(1.0, geometry, contact.theta_1, kin.theta_d), 1e-300
        )
        K2_0 = K1_0
        B_0 = K2_0 / max(hf.lam, 1e-12)
    return K1_0, K2_0, B_0


def _search_box(
    start: tuple[float, float, float], theta_1: float, theta_d: float, fit_theta_1: bool
) -> tuple[list[float], list[float], list[float], float]:
    """Start and bounds of the fit's parameters, and the start ``theta_1`` (moved just inside
    ``[0, theta_d)``): ``log K1, log K2, log B`` each within ``e^+-20`` of its start (a wild
    fit cannot overflow), then ``theta_1`` in ``[0, theta_d)`` when it is fitted."""
    th_hi = theta_d * (1.0 - 1e-9)
    theta_1_0 = min(max(theta_1, 0.0), th_hi * (1 - 1e-6))
    x0 = [math.log(v) for v in start]
    lb = [v - _LOG_SPAN for v in x0]
    ub = [v + _LOG_SPAN for v in x0]
    if fit_theta_1:
        x0.append(theta_1_0)
        lb.append(0.0)
        ub.append(th_hi)
    return x0, lb, ub, theta_1_0


def _clamp_hold_model(
    tt: NDArray[np.float64],
    geometry: ClampGeometry,
    kin: ClampKinematics,
    theta_1: float | None,
) -> Callable[[NDArray[np.float64]], NDArray[np.float64]]:
    """The exact clamp+hold moment at ``tt`` as a function of the fit's parameters
    ``(log K1, log K2, log B[, theta_1])``; ``theta_1`` given fixes the contact angle."""

    def model(p: NDArray[np.float64]) -> NDArray[np.float64]:
        k1, k2, b = np.exp(np.clip(p[:3], -700.0, 700.0))
        th1 = p[3] if theta_1 is None else theta_1
        S, V = moment_components(tt, geometry, th1, kin.theta_d, kin.omega, k2 / b, kin.t_start)
        return k1 * S + k2 * V

    return model


def _least_squares_fit(
    model: Callable[[NDArray[np.float64]], NDArray[np.float64]],
    w: NDArray[np.float64],
    m: NDArray[np.float64],
    x0: list[float],
    lb: list[float],
    ub: list[float],
) -> OptimizeResult:
    """``least_squares`` (TRF) of the weighted residuals ``w (model - m)`` within the bounds.

    A non-finite model (an overflowing corner of parameter space) is a huge residual, not a
    NaN that would poison the Jacobian; a solver exception becomes an :class:`EstimationError`.
    """

    def resid(p: NDArray[np.float64]) -> NDArray[np.float64]:
        with np.errstate(all="ignore"):
            r = w * (model(p) - m)
        return np.where(np.isfinite(r), r, 1e150)

    try:
        with np.errstate(all="ignore"):
            return least_squares(
                resid,
                np.asarray(x0),
                bounds=(lb, ub),
                **_trf(1e-12),
            )
    except (ValueError, ArithmeticError, np.linalg.LinAlgError) as exc:
        raise EstimationError(f"full fit failed: {type(exc).__name__}: {exc}") from None


def _fit_covariance(res: OptimizeResult, n: int) -> tuple[NDArray[np.float64], int]:
    """``s^2 (J^T J)^-1`` of a least-squares fit to ``n`` samples (inf where singular) and
    its degrees of freedom."""
    npar = res.x.size
    dof = max(n - npar, 1)
    s2 = 2.0 * float(res.cost) / dof
    J = np.asarray(res.jac, dtype=np.float64)
    cov = np.full((npar, npar), np.inf)
    if np.all(np.isfinite(J)) and np.isfinite(s2):
        with np.errstate(all="ignore"):
            try:
                jtj_inv = np.linalg.inv(J.T @ J)
                if np.all(np.isfinite(jtj_inv)):
                    cov = s2 * jtj_inv
            except np.linalg.LinAlgError:
                pass
    return cov, dof


def _full_fit_intervals(
    p: NDArray[np.float64],
    cov: NDArray[np.float64],
    q: float,
    params: SLSParams,
    th1: float,
) -> dict[str, tuple[float, float]]:
    """95 % intervals (Student-t quantile ``q``) of K1, K2, B from log space, theta_1 when
    fitted (a fourth parameter), and g1, tau1 by the delta method."""
    npar = p.size
    se = np.sqrt(np.clip(np.nan_to_num(np.diag(cov), nan=np.inf), 0.0, np.inf))
    intervals: dict[str, tuple[float, float]] = {}
    for i, name in enumerate(("K1", "K2", "B")):
        intervals[name] = (_safe_exp(p[i] - q * se[i]), _safe_exp(p[i] + q * se[i]))
    if npar > 3:
        intervals["theta_1"] = (th1 - q * se[3], th1 + q * se[3])
    g1, tau1 = params.to_prony()
    with np.errstate(all="ignore"):
        grad_g = np.zeros(npar)
        grad_g[0], grad_g[1] = -g1 * (1 - g1), g1 * (1 - g1)
        var_g = float(grad_g @ np.where(np.isfinite(cov), cov, np.inf) @ grad_g)
        se_g = math.sqrt(var_g) if np.isfinite(var_g) and var_g >= 0.0 else math.inf
        grad_lt = np.zeros(npar)
        grad_lt[1], grad_lt[2] = -1.0, 1.0
        var_lt = float(grad_lt @ np.where(np.isfinite(cov), cov, np.inf) @ grad_lt)
        se_lt = math.sqrt(var_lt) if np.isfinite(var_lt) and var_lt >= 0.0 else math.inf
    intervals["g1"] = (g1 - q * se_g, g1 + q * se_g)
    intervals["tau1"] = (tau1 * _safe_exp(-q * se_lt), tau1 * _safe_exp(q * se_lt))
    return intervals


def _full_fit_reliability(
    res: OptimizeResult,
    box: tuple[list[float], list[float]],
    cov: NDArray[np.float64],
    hf: HoldFit,
    tau1: float,
    intervals: dict[str, tuple[float, float]],
    r2_clamp: float,
) -> tuple[bool, list[str]]:
    """Whether the fit can be trusted, and why not: the solver converged inside its search
    ``box`` to identifiable parameters, and the checks both estimators share pass."""
    p = res.x
    lb, ub = box
    warns: list[str] = []
    reliable = bool(res.success)
    if not res.success:
        warns.append(f"least_squares did not converge: {res.message}")
    if np.any(np.isclose(p[:3], lb[:3])) or np.any(np.isclose(p[:3], ub[:3])):
        warns.append("a parameter hit its search bound (e^+-20 of the start): the fit is wild")
        reliable = False
    if not np.all(np.isfinite(cov)):
        warns.append("the fit's covariance is singular: parameters are not all identifiable")
        reliable = False
    vals = np.array([_safe_exp(v) for v in p[:3]])
    half = np.array([(intervals[k][1] - intervals[k][0]) / 2 for k in ("K1", "K2", "B")])
    reliable &= _reliability(hf, tau1, vals, half, warns, r2_clamp)
    return reliable, warns
