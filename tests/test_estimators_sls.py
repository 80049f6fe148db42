"""Tests of the rotational standard-linear-solid forward model (PAPER eqs. 1-7)."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose

from estimators.errors import EstimationError
from estimators.sls import (
    ClampGeometry,
    SLSParams,
    clamp_angle,
    eq4_coefficients,
    moment_trace,
    steady_moment,
)

GEOM = ClampGeometry(L=0.05, theta_0=0.17)
THETA_1 = 0.02
# g1 = 0.425, tau1 = 3.667 s (PAPER viscoelastic study), instantaneous stiffness 2000 N/m.
TRUE = SLSParams(K1=1150.0, K2=850.0, B=850.0 * 3.667)
CONFIGS = [(0.01, 0.0244), (0.03, 0.0244), (0.04, 0.0244), (0.1, 0.09), (0.05, 0.05)]


def _grid(omega: float, theta_d: float, hold: float = 10.0, fs: float = 100.0) -> np.ndarray:
    return np.arange(0.0, theta_d / omega + hold, 1.0 / fs)


def test_prony_values_and_round_trip() -> None:
    g1, tau1 = TRUE.to_prony()
    assert_allclose([g1, tau1], [0.425, 3.667], rtol=1e-12)
    back = SLSParams.from_prony(TRUE.K1 + TRUE.K2, g1, tau1)
    assert_allclose([back.K1, back.K2, back.B], [TRUE.K1, TRUE.K2, TRUE.B], rtol=1e-12)
    p = SLSParams.from_prony(0.2e6, 0.1, 0.5)
    assert_allclose(p.to_prony(), (0.1, 0.5), rtol=1e-12)
    assert_allclose(p.K1 + p.K2, 0.2e6, rtol=1e-12)


@pytest.mark.parametrize(("omega", "theta_d"), CONFIGS)
def test_quadrature_and_ivp_agree_with_closed_form(omega: float, theta_d: float) -> None:
    t = _grid(omega, theta_d)
    m_closed = moment_trace(t, TRUE, GEOM, THETA_1, theta_d, omega)
    m_quad = moment_trace(t, TRUE, GEOM, THETA_1, theta_d, omega, method="quadrature")
    m_ivp = moment_trace(t, TRUE, GEOM, THETA_1, theta_d, omega, method="ivp")
    scale = np.max(np.abs(m_ivp))
    assert scale > 0
    # 1e-6 relative to the peak moment (the brief's tolerance); observed ~1e-11.
    assert_allclose(m_quad, m_ivp, rtol=0, atol=1e-6 * scale)
    assert_allclose(m_closed, m_ivp, rtol=0, atol=1e-6 * scale)
    on = np.abs(m_ivp) > 1e-3 * scale
    assert_allclose(m_quad[on], m_ivp[on], rtol=1e-6)


@pytest.mark.parametrize(("omega", "theta_d"), CONFIGS)
def test_closed_form_satisfies_eq4(omega: float, theta_d: float) -> None:
    """Finite-difference residual of eq. 4 as printed in the paper, inside the clamp."""
    t1 = THETA_1 / omega
    td = theta_d / omega
    t = np.linspace(t1 + 0.05 * (td - t1), td - 0.05 * (td - t1), 50)
    h = 1e-6 * (td - t1)
    m = moment_trace(t, TRUE, GEOM, THETA_1, theta_d, omega)
    dm = (
        moment_trace(t + h, TRUE, GEOM, THETA_1, theta_d, omega)
        - moment_trace(t - h, TRUE, GEOM, THETA_1, theta_d, omega)
    ) / (2 * h)
    a, b, rhs = eq4_coefficients(omega * t, np.full_like(t, omega), TRUE, GEOM, THETA_1)
    assert_allclose(a * dm + b * m, rhs, rtol=1e-6)


def test_phases_zero_before_contact_continuous_and_relaxing_to_eq6() -> None:
    omega, theta_d = 0.02, 0.05
    t = np.linspace(0.0, theta_d / omega + 200.0, 20001)
    m = moment_trace(t, TRUE, GEOM, THETA_1, theta_d, omega)
    assert np.all(m[t <= THETA_1 / omega] == 0.0)
    assert np.all(m[t > THETA_1 / omega] > 0.0)
    td = theta_d / omega
    left, right = moment_trace([td - 1e-9, td + 1e-9], TRUE, GEOM, THETA_1, theta_d, omega)
    assert_allclose(left, right, rtol=1e-6)
    # After 200 s >> tau1 the hold reached M_inf of eq. 6.
    assert_allclose(m[-1], steady_moment(TRUE, GEOM, THETA_1, theta_d), rtol=1e-12)
    # Peak at t_d, then monotone relaxation.
    hold = m[t > td]
    assert np.all(np.diff(hold) <= 0)
    assert hold[0] - hold[-1] > 0.1 * hold[0]
    assert abs(t[m.argmax()] - td) <= t[1] - t[0]


def test_eq7_inverts_eq6() -> None:
    theta_d = 0.0244
    m_inf = steady_moment(TRUE, GEOM, THETA_1, theta_d)
    k1 = (
        m_inf
        * np.cos(GEOM.theta_0 - theta_d)
        / (GEOM.L**2 * (np.sin(GEOM.theta_0 - THETA_1) - np.sin(GEOM.theta_0 - theta_d)))
    )
    assert_allclose(k1, TRUE.K1, rtol=1e-12)


def test_no_compression_gives_zero_moment() -> None:
    t = _grid(0.01, 0.015)
    assert np.all(moment_trace(t, TRUE, GEOM, THETA_1, 0.015, 0.01) == 0.0)


def test_clamp_angle_and_t_start() -> None:
    th = clamp_angle([0.0, 1.0, 2.0, 3.0, 100.0], 0.05, 0.02, t_start=1.0)
    assert_allclose(th, [0.0, 0.0, 0.02, 0.04, 0.05])


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"omega": 0.0}, "omega"),
        ({"omega": -0.1}, "omega"),
        ({"theta_d": -0.01}, "theta_d"),
        ({"theta_1": -0.01}, "theta_1"),
        ({"method": "euler"}, "method"),
    ],
)
def test_forward_model_rejects_bad_arguments(kwargs: dict, match: str) -> None:
    args = {"theta_1": THETA_1, "theta_d": 0.03, "omega": 0.01} | kwargs
    with pytest.raises(EstimationError, match=match):
        moment_trace(np.arange(0.0, 5.0, 0.01), TRUE, GEOM, **args)


def test_params_and_geometry_validation() -> None:
    with pytest.raises(EstimationError, match="K1"):
        SLSParams(-1.0, 1.0, 1.0)
    with pytest.raises(EstimationError, match="B"):
        SLSParams(1.0, 1.0, 0.0)
    with pytest.raises(EstimationError, match="L"):
        ClampGeometry(0.0, 0.17)
    # an integer past int64 is a number too large, not a TypeError from numpy
    with pytest.raises(EstimationError, match="lever arm L must be in"):
        ClampGeometry(2**70, 0.17)
    with pytest.raises(EstimationError, match="theta_0"):
        ClampGeometry(0.05, -(2**70))
    with pytest.raises(EstimationError, match="g1"):
        SLSParams.from_prony(1.0, 1.5, 1.0)
