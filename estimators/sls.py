"""Standard linear solid (SLS) in the rotational form of the half-spoon clamp (PAPER eqs. 1-7).

The food is a spring ``K1`` (N/m) in parallel with a Maxwell arm (spring ``K2`` N/m in series with a
dashpot ``B`` N s/m). The half-spoon turns about its hinge; the hinge angle ``theta`` (rad) is 0 at
the open pose and grows while closing, ``theta_0`` (rad) is the fully closed angle and ``L`` (m)
the lever arm from the hinge axis to the equivalent contact section. The moment ``M`` (N m) of the
food on the half-spoon is positive when the food pushes the half-spoon open.

Derivation of eq. 4 (checked here; the paper's printed form is right). With
``phi = theta_0 - theta`` (so ``phi' = -theta'``):

* eq. 2, ``F_n = M cos(phi) / L``, gives
  ``F_n' = M' cos(phi) / L + M sin(phi) theta' / L``;
* eq. 3, ``x = L [sin(theta_0 - theta_1) - sin(phi)]``, gives ``x' = L cos(phi) theta'``;
* eq. 1, ``F_n' + (K2/B) F_n = (K1 + K2) x' + (K1 K2 / B) x``, then reads
  ``a M' + b M = c theta' + (K1 K2 / B) L [sin(theta_0 - theta_1) - sin(phi)]`` with
  ``a = cos(phi)/L``, ``b = [B sin(phi) theta' + K2 cos(phi)] / (B L)`` and
  ``c = (K1 + K2) L cos(phi)``, exactly as printed.

The integrating factor of eq. 4 is ``mu(t) = exp(int b/a dt) = cos(phi(t)) exp(t K2/B)``, so
``M(t) = L / cos(phi(t)) * int_{t_1}^{t} exp(-(t - s) K2/B) [(K1+K2) x'(s) + (K1 K2/B) x(s)] ds``,
i.e. ``F_n`` is the SLS force ``K1 x + K2 int exp(-(t-s)/tau_1) x'(s) ds`` (eq. 5). For a clamp at
constant ``omega`` that integral has a closed form (used by default, and by the fitters); a
step-wise integrating-factor quadrature and a ``solve_ivp`` integration of eq. 4 itself are given
as independent checks.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.integrate import solve_ivp

from estimators.errors import EstimationError, floats, instance, real

__all__ = [
    "ClampGeometry",
    "SLSParams",
    "clamp_angle",
    "displacement",
    "eq4_coefficients",
    "moment_components",
    "moment_trace",
    "steady_moment",
]

Method = Literal["closed", "quadrature", "ivp"]


MAX_LEVER_ARM = 1.0  # m: the longest half-spoon lever arm ClampGeometry takes


@dataclass(frozen=True)
class ClampGeometry:
    """Geometry of one half-spoon.

    Attributes:
        L: distance from the hinge axis to the equivalent contact section, m, in (0, 1]
            (a half-spoon's lever arm is centimetres; a metre is a unit slip).
        theta_0: hinge angle at which the half-spoon is fully closed, rad, within
            (-pi/2, pi/2) (the clamp's eq. 7 divides by cos(theta_0 + theta)).
    """

    L: float
    theta_0: float

    def __post_init__(self) -> None:
        # (checked as floats: numpy cannot test an integer too large for int64)
        lever, theta_0 = real("L", self.L), real("theta_0", self.theta_0)
        if not (np.isfinite(lever) and 0.0 < lever <= MAX_LEVER_ARM):
            raise EstimationError(f"lever arm L must be in (0, {MAX_LEVER_ARM:g}] m, "
                                  f"got {self.L!r}")
        if not (np.isfinite(theta_0) and abs(theta_0) < np.pi / 2):
            raise EstimationError(f"theta_0 must be within (-pi/2, pi/2) rad, got "
                                  f"{self.theta_0!r}")


@dataclass(frozen=True)
class SLSParams:
    """Standard linear solid: ``K1`` in parallel with (``K2`` in series with ``B``).

    ``K2 = B = 0`` is a food without a Maxwell arm: a spring ``K1`` alone, which never relaxes
    (``g1 = 0``, what :meth:`from_prony` gives for a Prony weight of 0).

    Attributes:
        K1: equilibrium spring, N/m (>= 0).
        K2: Maxwell-arm spring, N/m (>= 0; ``K1 + K2 > 0``, or ``g1`` would be 0/0).
        B: Maxwell-arm dashpot, N s/m (> 0; 0 only with ``K2 = 0``).
    """

    K1: float
    K2: float
    B: float

    def __post_init__(self) -> None:
        for name in ("K1", "K2", "B"):
            v = real(f"SLS parameter {name}", getattr(self, name))
            if not (np.isfinite(v) and v >= 0.0):
                raise EstimationError(f"SLS parameter {name} must be finite and >= 0, got {v!r}")
        if self.B == 0.0 and self.K2 > 0.0:
            raise EstimationError("SLS parameter B must be > 0 N s/m when K2 > 0 (only a "
                                  "food without a Maxwell arm, K2 = 0, has B = 0), got 0.0")
        if self.K1 + self.K2 == 0.0:
            raise EstimationError("SLS springs K1 + K2 must be > 0 N/m (g1 is undefined), "
                                  "got K1 = K2 = 0")

    @property
    def g1(self) -> float:
        """Prony weight ``K2 / (K1 + K2)`` (dimensionless)."""
        return self.K2 / (self.K1 + self.K2)

    @property
    def tau1(self) -> float:
        """Prony (Maxwell-arm) relaxation time ``B / K2``, s; infinite when ``K2 = 0`` (nothing
        relaxes)."""
        return self.B / self.K2 if self.K2 > 0.0 else np.inf

    @property
    def rate(self) -> float:
        """Maxwell-arm rate ``K2 / B = 1 / tau1``, 1/s; 0 without a Maxwell arm (``B = 0``),
        where the arm carries no force whatever its rate."""
        return self.K2 / self.B if self.B > 0.0 else 0.0

    def to_prony(self) -> tuple[float, float]:
        """Return the one-term Prony series ``(g1, tau1)`` (dimensionless, s)."""
        return self.g1, self.tau1

    @classmethod
    def from_prony(cls, K_instant: float, g1: float, tau1: float) -> SLSParams:
        """Build from the instantaneous stiffness and a one-term Prony series.

        Args:
            K_instant: instantaneous stiffness ``K1 + K2`` (N/m), the scale playing the role of
                ``E_0`` in ``E(t) = E_0 [1 - g1 (1 - exp(-t / tau1))]``.
            g1: Prony weight in [0, 1); 0 is a food that does not relax, giving
                ``K2 = B = 0`` (no Maxwell arm; :attr:`tau1` is then infinite).
            tau1: relaxation time, s (finite, > 0; irrelevant when ``g1 = 0``).
        """
        K_instant = real("K_instant", K_instant)
        g1 = real("g1", g1)
        tau1 = real("tau1", tau1)
        if not (np.isfinite(K_instant) and K_instant > 0.0):
            raise EstimationError(
                f"instantaneous stiffness K_instant must be finite and > 0 N/m, got {K_instant!r}")
        if not (0.0 <= g1 < 1.0):
            raise EstimationError(f"Prony weight g1 must be in [0, 1), got {g1!r}")
        if not (tau1 > 0.0 and np.isfinite(tau1)):
            raise EstimationError(f"Prony time tau1 must be finite and > 0 s, got {tau1!r}")
        k2 = g1 * K_instant
        return cls(K1=K_instant - k2, K2=k2, B=tau1 * k2)


def clamp_angle(
    t: ArrayLike, theta_d: float, omega: float, t_start: float = 0.0
) -> NDArray[np.float64]:
    """Hinge angle (rad) of a clamp at constant ``omega`` (rad/s) from 0 at ``t_start`` (s)."""
    theta_d, omega, t_start = (real(n, v) for n, v in (("theta_d", theta_d), ("omega", omega),
                                                       ("t_start", t_start)))
    return np.clip(omega * (floats("t", t) - t_start), 0.0, theta_d)


def displacement(theta: ArrayLike, geometry: ClampGeometry, theta_1: float) -> NDArray[np.float64]:
    """Equivalent food compression ``x`` (m) of eq. 3; negative before first contact."""
    _check_geometry(geometry)
    theta_1 = real("theta_1", theta_1)
    th = floats("theta", theta)
    return geometry.L * (np.sin(geometry.theta_0 - theta_1) - np.sin(geometry.theta_0 - th))


def eq4_coefficients(
    theta: ArrayLike,
    theta_dot: ArrayLike,
    params: SLSParams,
    geometry: ClampGeometry,
    theta_1: float,
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Return ``(a, b, rhs)`` of eq. 4, ``a M' + b M = rhs``.

    ``a`` in 1/m, ``b`` in 1/(m s), ``rhs = c theta' + (K1 K2 / B) x`` in N/s.
    """
    instance("params", params, SLSParams, "an SLSParams")
    _check_geometry(geometry)
    th, thd = floats("theta", theta), floats("theta_dot", theta_dot)
    k1, k2, bb = params.K1, params.K2, params.B
    L = geometry.L
    phi = geometry.theta_0 - th
    a = np.cos(phi) / L
    c = (k1 + k2) * L * np.cos(phi)
    if bb == 0.0:  # no Maxwell arm (K2 = B = 0): eq. 1 is F_n' = K1 x'
        return a, np.sin(phi) * thd / L, c * thd
    b = (bb * np.sin(phi) * thd + k2 * np.cos(phi)) / (bb * L)
    rhs = c * thd + (k1 * k2 / bb) * displacement(th, geometry, theta_1)
    return a, b, rhs


def steady_moment(
    params: SLSParams | float, geometry: ClampGeometry, theta_1: float, theta_d: float
) -> float:
    """Relaxed moment ``M_inf`` (N m) of eq. 6 at hold angle ``theta_d`` (rad).

    ``params`` may be an :class:`SLSParams` or just ``K1`` (N/m).
    """
    k1 = params.K1 if isinstance(params, SLSParams) else real("K1", params)
    _check_geometry(geometry)
    for name, value in (("theta_1", theta_1), ("theta_d", theta_d)):
        if not np.isfinite(real(name, value)):
            raise EstimationError(f"{name} must be finite, got {value!r}")
    if theta_d <= theta_1:
        return 0.0
    L, th0 = geometry.L, geometry.theta_0
    return k1 * L**2 * (np.sin(th0 - theta_1) - np.sin(th0 - theta_d)) / np.cos(th0 - theta_d)


def _check_geometry(geometry: object) -> None:
    instance("geometry", geometry, ClampGeometry, "a ClampGeometry (L, theta_0)")


def _check_clamp(geometry: ClampGeometry, theta_1: float, theta_d: float, omega: float) -> None:
    _check_geometry(geometry)
    for name, value in (("omega", omega), ("theta_d", theta_d), ("theta_1", theta_1)):
        real(name, value)
    if not (np.isfinite(omega) and omega > 0.0):
        raise EstimationError(
            f"clamping velocity omega must be finite and > 0 rad/s, got {omega!r}"
        )
    if not (np.isfinite(theta_d) and theta_d > 0.0):
        raise EstimationError(f"hold angle theta_d must be finite and > 0 rad, got {theta_d!r}")
    if not np.isfinite(theta_1):
        raise EstimationError(f"contact angle theta_1 must be finite, got {theta_1!r}")
    if np.cos(geometry.theta_0 - max(theta_d, theta_1)) <= 0.0:
        raise EstimationError(
            f"theta_d={theta_d!r} is beyond theta_0 + pi/2 (theta_0={geometry.theta_0!r}); "
            "the normal-force projection cos(theta_0 - theta) must stay > 0"
        )


def _relax_integral(T: NDArray[np.float64], phi1: float, omega: float, lam: float):
    """``I(T) = int_0^T exp(-lam (T - u)) cos(phi1 - omega u) du`` in closed form (s)."""
    den = lam * lam + omega * omega
    arg = phi1 - omega * T
    return (
        lam * np.cos(arg)
        - omega * np.sin(arg)
        - np.exp(-lam * T) * (lam * np.cos(phi1) - omega * np.sin(phi1))
    ) / den


def moment_components(
    t: ArrayLike,
    geometry: ClampGeometry,
    theta_1: float,
    theta_d: float,
    omega: float,
    lam: float,
    t_start: float = 0.0,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Split the exact moment into ``M = K1 * S + K2 * V`` (closed form).

    Args:
        t: sample times, s.
        geometry: clamp geometry.
        theta_1: contact angle, rad.
        theta_d: hold angle, rad.
        omega: clamping velocity, rad/s.
        lam: Maxwell-arm rate ``K2 / B = 1 / tau1``, 1/s.
        t_start: time at which the clamp leaves ``theta = 0``, s.

    Returns:
        ``(S, V)`` in m^2 (N m per N/m): ``S`` the equilibrium-spring part, ``V`` the Maxwell-arm
        part; both zero before contact. ``M`` is linear in ``K1`` and ``K2`` once ``lam`` is fixed,
        which makes both the fits and step 3 (K2 from the peak, in closed form) cheap.
    """
    _check_clamp(geometry, theta_1, theta_d, omega)
    lam, t_start = real("lam", lam), real("t_start", t_start)
    tt = floats("t", t)
    S = np.zeros_like(tt)
    V = np.zeros_like(tt)
    if theta_1 < 0.0:
        raise EstimationError(f"contact angle theta_1 must be >= 0 rad, got {theta_1!r}")
    if theta_d <= theta_1:
        return S, V
    L, th0 = geometry.L, geometry.theta_0
    t1 = t_start + theta_1 / omega
    td = t_start + theta_d / omega
    theta = clamp_angle(tt, theta_d, omega, t_start)
    phi = th0 - theta
    contact = tt > t1
    x = L * (np.sin(th0 - theta_1) - np.sin(phi[contact]))
    S[contact] = L * x / np.cos(phi[contact])
    phi1 = th0 - theta_1
    # The Maxwell arm sees x' = L cos(phi) theta' only while the clamp moves (t1 < t < td).
    Td = td - t1
    i_d = _relax_integral(np.asarray(Td), phi1, omega, lam)
    V_d = L * L * omega * i_d / np.cos(th0 - theta_d)
    clamp = contact & (tt <= td)
    V[clamp] = (
        L * L * omega * _relax_integral(tt[clamp] - t1, phi1, omega, lam) / np.cos(phi[clamp])
    )
    hold = tt > td
    V[hold] = V_d * np.exp(-lam * (tt[hold] - td))
    return S, V


def _moment_quadrature(tt: NDArray[np.float64], params: SLSParams, geometry: ClampGeometry,
                       theta_1: float, theta_d: float, omega: float, t_start: float,
                       n_sub: int) -> NDArray[np.float64]:
    """Integrating-factor solution of eq. 4 by step-wise composite Simpson quadrature.

    Between consecutive grid times ``t_k < t_{k+1}`` (the output times in the clamp plus ``t_1`` and
    ``t_d``) the integrating factor gives ``F(t_{k+1}) = exp(-lam h) F(t_k) +
    int_{t_k}^{t_{k+1}} exp(-lam (t_{k+1} - s)) rhs(s) ds``, with ``F = M cos(phi) / L`` and
    ``rhs`` eq. 4's right-hand side; each step integral uses ``n_sub`` Simpson panels. Stepping
    (rather than one global ``exp(lam s)`` factor) keeps it free of overflow.
    """
    lam = params.rate
    L, th0 = geometry.L, geometry.theta_0
    t1 = t_start + theta_1 / omega
    td = t_start + theta_d / omega
    out = np.zeros_like(tt)
    in_clamp = (tt > t1) & (tt <= td)
    grid = np.unique(np.concatenate(([t1], tt[in_clamp], [td])))
    h = np.diff(grid)
    # Simpson nodes: 2*n_sub panels per step -> 2*n_sub + 1 nodes, weights 1,4,2,...,4,1.
    m = 2 * n_sub
    u = np.linspace(0.0, 1.0, m + 1)
    w = np.ones(m + 1)
    w[1:-1:2] = 4.0
    w[2:-1:2] = 2.0
    s = grid[:-1, None] + h[:, None] * u[None, :]
    theta_s = omega * (s - t_start)
    _, _, rhs = eq4_coefficients(theta_s, np.full_like(s, omega), params, geometry, theta_1)
    kern = np.exp(-lam * (grid[1:, None] - s))
    q = (h / (3.0 * m)) * np.sum(w * kern * rhs, axis=1)
    decay = np.exp(-lam * h)
    F = np.empty_like(grid)
    F[0] = 0.0
    for k in range(h.size):
        F[k + 1] = decay[k] * F[k] + q[k]
    theta_grid = np.clip(omega * (grid - t_start), 0.0, theta_d)
    M_grid = F * L / np.cos(th0 - theta_grid)
    out[in_clamp] = np.interp(tt[in_clamp], grid, M_grid)
    M_d = M_grid[-1]
    hold = tt > td
    M_inf = steady_moment(params, geometry, theta_1, theta_d)
    out[hold] = M_inf + (M_d - M_inf) * np.exp(-lam * (tt[hold] - td))
    return out


def _moment_ivp(tt: NDArray[np.float64], params: SLSParams, geometry: ClampGeometry, theta_1: float,
                theta_d: float, omega: float, t_start: float, rtol: float) -> NDArray[np.float64]:
    """Integrate eq. 4 with ``scipy.integrate.solve_ivp`` through the clamp and the hold."""
    t1 = t_start + theta_1 / omega
    td = t_start + theta_d / omega
    out = np.zeros_like(tt)

    def rhs_fn(theta_dot: float):
        def f(tv: float, y: NDArray[np.float64]) -> NDArray[np.float64]:
            theta = min(max(omega * (tv - t_start), 0.0), theta_d)
            a, b, r = eq4_coefficients(theta, theta_dot, params, geometry, theta_1)
            return np.array([(r - b * y[0]) / a])

        return f

    scale = max(params.K1 + params.K2, 1e-300) * geometry.L**2 * (theta_d - theta_1)
    atol = 1e-14 * scale
    clamp = (tt > t1) & (tt <= td)
    ev = np.unique(np.concatenate((tt[clamp], [td])))
    sol = solve_ivp(
        rhs_fn(omega), (t1, td), [0.0], method="DOP853", t_eval=ev, rtol=rtol, atol=atol
    )
    if not sol.success:  # pragma: no cover - DOP853 on a smooth linear ODE
        raise EstimationError(f"solve_ivp failed in the clamp: {sol.message}")
    out[clamp] = sol.y[0, np.searchsorted(ev, tt[clamp])]
    M_d = sol.y[0, -1]
    hold = tt > td
    if hold.any():
        ev2 = np.unique(tt[hold])
        sol2 = solve_ivp(
            rhs_fn(0.0),
            (td, ev2[-1]),
            [M_d],
            method="DOP853",
            t_eval=ev2,
            rtol=rtol,
            atol=atol,
        )
        if not sol2.success:  # pragma: no cover
            raise EstimationError(f"solve_ivp failed in the hold: {sol2.message}")
        out[hold] = sol2.y[0, np.searchsorted(ev2, tt[hold])]
    return out


def moment_trace(
    t: ArrayLike,
    params: SLSParams,
    geometry: ClampGeometry,
    theta_1: float,
    theta_d: float,
    omega: float,
    t_start: float = 0.0,
    method: Method = "closed",
    *,
    n_sub: int = 8,
    rtol: float = 1e-11,
) -> NDArray[np.float64]:
    """Moment ``M(t)`` (N m) of the food on a half-spoon for a clamp-and-hold.

    The half-spoon leaves ``theta = 0`` at ``t_start`` (s), closes at ``omega`` (rad/s), touches
    the food at ``theta_1`` (rad; ``t_1 = t_start + theta_1 / omega``), reaches ``theta_d`` (rad)
    at ``t_d = t_start + theta_d / omega`` and holds it. ``M = 0`` before contact; eq. 4 with
    ``M(t_1) = 0`` in the clamp; eq. 6 in the hold.

    Args:
        t: sample times, s (any order; evaluated pointwise).
        params: SLS parameters.
        geometry: clamp geometry.
        theta_1: first-contact angle, rad.
        theta_d: hold angle, rad.
        omega: clamping velocity, rad/s.
        t_start: time the clamp starts from ``theta = 0``, s.
        method: ``"closed"`` (exact closed form, fast), ``"quadrature"`` (integrating-factor
            Simpson quadrature of eq. 4) or ``"ivp"`` (``solve_ivp`` of eq. 4, slow, reference).
        n_sub: Simpson panel pairs per sample step (``"quadrature"`` only).
        rtol: relative tolerance (``"ivp"`` only).
    """
    _check_clamp(geometry, theta_1, theta_d, omega)
    instance("params", params, SLSParams, "an SLSParams")
    if not np.isfinite(real("t_start", t_start)):
        raise EstimationError(f"t_start must be finite, got {t_start!r}")
    if isinstance(n_sub, bool) or not isinstance(n_sub, int | np.integer) or n_sub < 1:
        raise EstimationError(f"n_sub must be an integer >= 1, got {n_sub!r}")
    tt = floats("t", t)
    if theta_d <= theta_1:
        return np.zeros_like(tt)
    if theta_1 < 0.0:
        raise EstimationError(f"contact angle theta_1 must be >= 0 rad, got {theta_1!r}")
    if method == "closed":
        S, V = moment_components(tt, geometry, theta_1, theta_d, omega, params.rate, t_start)
        return params.K1 * S + params.K2 * V
    if method == "quadrature":
        return _moment_quadrature(tt, params, geometry, theta_1, theta_d, omega, t_start, n_sub)
    if method == "ivp":
        return _moment_ivp(tt, params, geometry, theta_1, theta_d, omega, t_start, rtol)
    raise EstimationError(f"unknown method {method!r}; use 'closed', 'quadrature' or 'ivp'")
