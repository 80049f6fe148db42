"""The trace recorder: its batched meters against the same meters run on each sample alone."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from fetch_env import recording
from fetch_env.layouts import diced_mix
from fetch_env.recording import TraceRecorder
from fetch_env.scene import build_scene, initial_state

# Which samples are metered, and which of those have fresh strain: holds of both kinds, and
# (with a chunk of 3) metered samples that straddle chunk boundaries.
METERED = [True, True, False, True, True, False, False, True, True, True, False]
FRESH = [True, False, False, True, False, False, False, True, True, False, False]


def test_batched_meters_equal_each_sample_metered_alone(monkeypatch: pytest.MonkeyPatch) -> None:
    """Each trace the recorder returns equals its meter run on that sample's state alone; a
    sample that is not metered holds the last metered sample's overlap and strain, and a
    metered one with stale strain the last fresh strain."""
    monkeypatch.setattr(recording, "CHUNK", 3)
    scene = build_scene(diced_mix(np.random.default_rng(3), n_pieces=6))
    m = scene.model
    # (awake: the states below are set by hand, not stepped, so nothing would wake a piece)
    m.opt.enableflags &= ~int(mujoco.mjtEnableBit.mjENBL_SLEEP)
    d = initial_state(scene)
    recorder = TraceRecorder(scene, d, n_samples=len(METERED))
    blades = recorder.overlap.geoms
    hinges = [m.jnt_qposadr[scene.ids[f"hinge_{side}"]] for side in ("left", "right")]
    q0 = d.qpos.copy()
    rng = np.random.default_rng(0)
    want: dict[str, list] = {k: [] for k in ("moment", "normal", "tangential", "force",
                                             "overlap", "strain")}
    lowest = np.full(len(scene.pieces), np.inf)
    deepest = np.zeros(len(scene.pieces))
    for metered, fresh in zip(METERED, FRESH, strict=True):
        # A new state at every sample: nodes jiggled by ~0.1 mm, and the blades closed past
        # the food's sides by a varying angle, so that they press on it and every meter moves.
        d.qpos[:] = q0 + rng.normal(scale=1e-4, size=q0.shape)
        d.qpos[hinges] = scene.pose.theta_open + rng.uniform(0.12, 0.18)
        mujoco.mj_forward(m, d)
        recorder.sample(metered, fresh)
        reading = recorder.sensors.read(d)
        for k in ("moment", "normal", "tangential", "force"):
            want[k].append(reading[k])
        if metered:
            xpos = np.array(d.flexvert_xpos)[None]
            reach = recorder.positions.piece_max(recorder.overlap.of(
                xpos, d.geom_xpos[blades][None], d.geom_xmat[blades][None]))[0]
            overlap = reach.max()
            deepest = np.maximum(deepest, reach)
            lowest = np.minimum(lowest, recorder.positions.lowest_of(xpos)[0])
        want["overlap"].append(overlap)
        if fresh:
            strain = recorder.strain.piece_strain(d)
        want["strain"].append(strain)
    readings, overlap_trace, strain_trace = recorder.finish()
    for k in ("moment", "normal", "tangential", "force"):
        np.testing.assert_allclose(readings[k], want[k], rtol=1e-12, atol=1e-15, err_msg=k)
    np.testing.assert_allclose(overlap_trace, want["overlap"], rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(strain_trace, want["strain"], rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(recorder.lowest_z, lowest, rtol=1e-12)
    np.testing.assert_allclose(recorder.max_overlap, deepest, rtol=1e-12)
    # the states differ enough that a wrong sample's value would show
    assert np.abs(np.asarray(want["moment"])).max() > 1e-3  # the blades press on the food
    assert len({round(float(s), 9) for s in np.asarray(want["strain"])[:, 0]}) == sum(FRESH)
    assert len({round(float(o), 9) for o in want["overlap"]}) == sum(METERED)


def test_a_run_must_start_with_a_metered_sample() -> None:
    scene = build_scene(diced_mix(np.random.default_rng(3), n_pieces=6))
    recorder = TraceRecorder(scene, initial_state(scene), n_samples=2)
    recorder.sample(metered=False, fresh_strain=False)
    with pytest.raises(ValueError, match="first sample"):
        recorder.finish()
