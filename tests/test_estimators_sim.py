"""The estimators validated against the simulator (the study's two virtual experiments).

Viscoelastic: a 15 mm, 0.2 MPa cube, g1 = 0.425, tau1 = 3.667 s, clamped to 0.0244 rad and held
25 s; the full fit of the measured angle and the moment averaged over both half-spoons must give
g1 and tau1 within 3 % (the issue's bar; the study's own deviations, 0.941 % / 0.164 %, are the
goal and are not met at every omega, see docs/reproducing.md).  One omega in the default
suite, all four marked slow.

Friction: mu within 1.4 % (the study's worst case) for cube, ellipsoid and sphere; one mu per
shape in the default suite, the other three marked slow.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from fetch_env.layouts import single_block
from fetch_env.materials import PRESETS
from fetch_env.study_probes import run_relaxation_probe, run_slip_probe

G1, TAU1 = 0.425, 3.667
VISCO_TOL = 0.03
MU_TOL = 0.014


def _relaxation(omega: float) -> None:
    material = PRESETS["soft-0.2MPa"]
    assert (material.g1, material.tau1) == (G1, TAU1)
    r = run_relaxation_probe(single_block("cube", 0.015, material), 0.0244, omega, 25.0)
    est = r["estimate"]
    assert est is not None, r["error"]
    assert abs(est.g1 / G1 - 1) < VISCO_TOL, est
    assert abs(est.tau1 / TAU1 - 1) < VISCO_TOL, est
    assert est.r2_clamp > 0.95 and est.r2_hold > 0.99
    assert est.reliable, est.warnings


def test_relaxation_g1_tau1_within_3_percent_at_0_02() -> None:
    _relaxation(0.02)


@pytest.mark.slow
@pytest.mark.parametrize("omega", [0.01, 0.03, 0.04])
def test_relaxation_g1_tau1_within_3_percent(omega: float) -> None:
    _relaxation(omega)


def _slip(shape: str, mu: float) -> None:
    material = dataclasses.replace(PRESETS["soft-0.2MPa"], mu=mu)
    r = run_slip_probe(single_block(shape, 0.015, material))
    est = r["estimate"]
    assert est is not None, r["error"]
    assert abs(est.mu / mu - 1) < MU_TOL, (shape, mu, est)
    assert est.interval[0] <= est.mu <= est.interval[1]
    assert np.isfinite(est.mu_left) and np.isfinite(est.mu_right)


@pytest.mark.parametrize(("shape", "mu"), [("cube", 0.3), ("ellipsoid", 0.5), ("sphere", 0.1)])
def test_friction_within_1_4_percent(shape: str, mu: float) -> None:
    _slip(shape, mu)


@pytest.mark.slow
@pytest.mark.parametrize(
    ("shape", "mu"),
    [
        (s, m)
        for s in ("cube", "ellipsoid", "sphere")
        for m in (0.1, 0.2, 0.3, 0.5)
        if (s, m) not in {("cube", 0.3), ("ellipsoid", 0.5), ("sphere", 0.1)}
    ],
)
def test_friction_within_1_4_percent_every_shape_and_mu(shape: str, mu: float) -> None:
    _slip(shape, mu)
