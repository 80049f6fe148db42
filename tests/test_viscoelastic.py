"""The Prony relaxation is consistent with MuJoCo's own flex elasticity.

The corotated displacement we compute must reproduce MuJoCo's elastic force ``qfrc_passive``
exactly (same R, same K), for every shape, on randomly deformed and rotated pieces; and the
rest-shape shift that carries the viscous stress must change MuJoCo's force by exactly the
viscous force ``-g_1 R K u_1`` (to first order in the strain), so that a fully relaxed piece
carries ``1 - g_1`` of its instantaneous elastic force.
"""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from fetch_env.layouts import SHAPES, Piece
from fetch_env.materials import Material
from fetch_env.scene import build_scene, initial_state
from fetch_env.viscoelastic import PronyRelaxation


def _svd_rotation(x: np.ndarray, grad: np.ndarray) -> np.ndarray:
    """Reference: the polar rotation of F = sum_i x_i (x) dN_i by SVD, (P, 3, 3)."""
    U, _, Vt = np.linalg.svd(x.transpose(0, 2, 1) @ grad)
    return U @ Vt


def _deform(scene, d, rng, scale, angle):
    m = scene.model
    prony = PronyRelaxation(scene)
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
def test_corotated_displacement_reproduces_mujocos_elastic_force(shape: str,
                                                                 young: float) -> None:
    scene = build_scene([Piece(shape, 0.015, Material(young=young, g1=0.425))])
    d = initial_state(scene)
    rng = np.random.default_rng(7)
    for scale, angle in ((2e-4, 0.0), (8e-4, 0.7), (1.5e-3, 2.0)):
        prony = _deform(scene, d, rng, scale, angle)
        elastic = d.qfrc_passive[prony.dofs].reshape(8, 3)
        u, _ = prony._corotated(d)
        # with the lagged state at -u/g1, the "viscous" force is +R K u: the elastic force
        ours = prony.viscous_force(d, -u[:, None, :] / 0.425)[0]
        np.testing.assert_allclose(ours, elastic, rtol=1e-7,
                                   atol=1e-9 * np.abs(elastic).max())


@pytest.mark.parametrize("shape", SHAPES)
@pytest.mark.parametrize("young", [0.0123e6, 200e6])
def test_relaxed_rest_shift_leaves_one_minus_g1_of_the_elastic_force(shape: str,
                                                                     young: float) -> None:
    """Fully relaxed (lagged state = current displacement), MuJoCo's force with the shifted
    rest shape is (1 - g_1) times the force without it, within 0.2 % at strains to ~1 %."""
    g1 = 0.425
    scene = build_scene([Piece(shape, 0.015, Material(young=young, g1=g1))])
    d = initial_state(scene)
    rng = np.random.default_rng(11)
    for scale, angle in ((2e-5, 0.0), (1e-4, 0.7), (1e-4, 2.0)):
        prony = _deform(scene, d, rng, scale, angle)
        elastic = d.qfrc_passive[prony.dofs].copy()
        prony.reset(d)  # relaxed here: rest shape moved by g1 u
        mujoco.mj_forward(scene.model, d)
        shifted = d.qfrc_passive[prony.dofs].copy()
        prony.restore()
        mujoco.mj_forward(scene.model, d)
        np.testing.assert_allclose(d.qfrc_passive[prony.dofs], elastic, rtol=0, atol=0)
        np.testing.assert_allclose(shifted, (1 - g1) * elastic, rtol=0,
                                   atol=2e-3 * np.abs(elastic).max())


def test_elastic_force_is_translation_and_rotation_free() -> None:
    """A rigid motion of the piece stores no elastic or viscous force."""
    scene = build_scene([Piece("cube", 0.015, Material())])
    d = initial_state(scene)
    prony = _deform(scene, d, np.random.default_rng(0), 0.0, 1.1)
    u, _ = prony._corotated(d)
    assert np.abs(d.qfrc_passive[prony.dofs]).max() < 1e-9
    assert np.abs(prony.viscous_force(d, u[:, None, :])).max() < 1e-9


def test_step_relaxation_of_the_lagged_state_is_exponential() -> None:
    """Holding a deformation, the elastic force decays as 1 - g_1 (1 - exp(-t / tau_1))."""
    g1, tau1 = 0.425, 0.5
    scene = build_scene([Piece("cube", 0.015, Material(g1=g1, tau1=tau1))])
    d = initial_state(scene)
    prony = _deform(scene, d, np.random.default_rng(3), 1e-4, 0.3)
    elastic = d.qfrc_passive[prony.dofs].copy()
    prony.lagged[:] = 0.0  # the rest state: a step strain applied now
    qpos = d.qpos.copy()
    dt = scene.model.opt.timestep
    steps = round(tau1 / dt)
    for _ in range(steps):
        d.qpos[:] = qpos  # hold the deformation exactly
        mujoco.mj_kinematics(scene.model, d)
        prony.apply(d)
    mujoco.mj_forward(scene.model, d)
    expected = (1 - g1 * (1 - np.exp(-steps * dt / tau1))) * elastic
    prony.restore()
    np.testing.assert_allclose(d.qfrc_passive[prony.dofs], expected, rtol=0,
                               atol=2e-3 * np.abs(elastic).max())


def test_a_run_leaves_the_compiled_rest_shape() -> None:
    """The rest shape moves during a run and is put back after it, even if it fails."""
    from fetch_env.controller import FetchAction, FetchSimulator

    sim = FetchSimulator([Piece("cube", 0.015, Material())])
    model = sim.scene_for("fetch").model
    before = model.flex_node0.copy()
    moved = []
    sim.run("fetch", FetchAction(theta_d=0.045, hold=0.1, air_hold=0.1),
            observer=lambda d: moved.append(np.abs(model.flex_node0 - before).max()))
    assert max(moved) > 1e-6  # it did move (a 0.2 MPa cube squeezed by ~1 mm)
    np.testing.assert_array_equal(model.flex_node0, before)


def test_steps_deferred_while_asleep_catch_up_exactly() -> None:
    """While every piece sleeps its nodes are frozen, so ``u`` is constant and k deferred
    steps plus one awake step must equal k + 1 ordinary steps (exp(-(k+1) dt / tau))."""
    scene = build_scene([Piece("cube", 0.015, Material(g1=0.425, tau1=0.5))])
    d = initial_state(scene)
    prony = _deform(scene, d, np.random.default_rng(5), 1e-4, 0.2)
    start = np.random.default_rng(6).normal(scale=1e-4, size=prony.lagged.shape)
    results = []
    for deferred in (False, True):
        prony.lagged[:] = start
        for _ in range(40):
            prony.apply(d, asleep=deferred)
        prony.apply(d)
        results.append((prony.lagged.copy(), scene.model.flex_node0.copy()))
    prony.restore()
    np.testing.assert_allclose(results[1][0], results[0][0], rtol=1e-12, atol=1e-18)
    np.testing.assert_allclose(results[1][1], results[0][1], rtol=1e-12, atol=1e-18)
    # and it did relax: 41 steps of 5 ms at tau 0.5 s move u_k ~34 % of the way to u
    assert np.abs(results[0][0] - start).max() > 1e-5


@pytest.mark.parametrize("shape", SHAPES)
def test_warm_started_rotation_is_the_polar_rotation(shape: str) -> None:
    """MuJoCo's mju_mat2Rot, warm-started from the last step, gives the SVD's polar rotation,
    cold (identity start, up to ~100 degrees away) and along a rotating, deforming path."""
    scene = build_scene([Piece(shape, 0.012, Material())])
    d = initial_state(scene)
    rng = np.random.default_rng(8)
    prony = PronyRelaxation(scene)
    prony.reset(d)
    for k in range(12):
        _deform(scene, d, rng, 5e-4, 0.15 * k)
        _, R = prony._corotated(d)
        x = d.xpos[prony.node_bodies]
        x -= x.mean(axis=1, keepdims=True)
        np.testing.assert_allclose(R, _svd_rotation(x, prony.grad), rtol=0, atol=1e-8)
