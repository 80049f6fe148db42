"""The Prony forces are exactly consistent with MuJoCo's own flex elasticity.

With the lagged displacement equal to the current corotated displacement (fully relaxed), the
viscous force must be exactly -g_1 times MuJoCo's elastic force ``qfrc_passive`` on the same
nodes, for every shape, on randomly deformed and rotated pieces.
"""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from fetch_env.layouts import SHAPES, Piece
from fetch_env.materials import Material
from fetch_env.scene import build_scene, initial_state
from fetch_env.viscoelastic import PronyForces


def _deform(scene, d, rng, scale, angle):
    m = scene.model
    prony = PronyForces(scene)
    nodes = prony.node_bodies[0]
    qadr = np.concatenate([m.jnt_qposadr[m.body_jntadr[b]] + np.arange(3) for b in nodes])
    rest = m.body_pos[nodes]
    c, s = np.cos(angle), np.sin(angle)
    rot = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]]) @ np.array(
        [[1, 0, 0], [0, np.cos(angle / 2), -np.sin(angle / 2)],
         [0, np.sin(angle / 2), np.cos(angle / 2)]])
    deformed = (rest + rng.normal(scale=scale, size=rest.shape)) @ rot.T
    d.qpos[qadr] = (deformed - rest).ravel()
    mujoco.mj_forward(m, d)
    return prony


@pytest.mark.parametrize("shape", SHAPES)
@pytest.mark.parametrize("young", [0.0123e6, 0.2e6, 200e6])
def test_relaxed_viscous_force_is_minus_g1_times_elastic(shape: str, young: float) -> None:
    g1 = 0.425
    scene = build_scene([Piece(shape, 0.015, Material(young=young, g1=g1))])
    d = initial_state(scene)
    rng = np.random.default_rng(7)
    for scale, angle in ((2e-4, 0.0), (8e-4, 0.7), (1.5e-3, 2.0)):
        prony = _deform(scene, d, rng, scale, angle)
        elastic = d.qfrc_passive[prony.dofs].reshape(8, 3)
        u, _ = prony._corotated(d)
        viscous = prony.viscous_force(d, u[:, None, :])[0]
        np.testing.assert_allclose(viscous, -g1 * elastic, rtol=1e-7,
                                   atol=1e-9 * np.abs(elastic).max())


def test_elastic_force_is_translation_and_rotation_free() -> None:
    """A rigid motion of the piece stores no elastic or viscous force."""
    scene = build_scene([Piece("cube", 0.015, Material())])
    d = initial_state(scene)
    prony = _deform(scene, d, np.random.default_rng(0), 0.0, 1.1)
    u, _ = prony._corotated(d)
    assert np.abs(d.qfrc_passive[prony.dofs]).max() < 1e-9
    assert np.abs(prony.viscous_force(d, u[:, None, :])).max() < 1e-9


def test_step_relaxation_of_the_lagged_state_is_exponential() -> None:
    """Holding a deformation, the viscous force decays as g_1 (1 - exp(-t / tau_1)) of it."""
    g1, tau1 = 0.425, 0.5
    scene = build_scene([Piece("cube", 0.015, Material(g1=g1, tau1=tau1))])
    d = initial_state(scene)
    prony = _deform(scene, d, np.random.default_rng(3), 5e-4, 0.3)
    elastic = d.qfrc_passive[prony.dofs].copy()
    prony.lagged[:] = 0.0  # the rest state: a step strain applied now
    qpos = d.qpos.copy()
    dt = scene.model.opt.timestep
    steps = round(tau1 / dt)
    for _ in range(steps):
        d.qpos[:] = qpos  # hold the deformation exactly
        mujoco.mj_kinematics(scene.model, d)
        prony.apply(d)
    f = d.qfrc_applied[prony.dofs]
    expected = -g1 * (1 - np.exp(-steps * dt / tau1)) * elastic
    np.testing.assert_allclose(f, expected, rtol=1e-6, atol=1e-9 * np.abs(elastic).max())
