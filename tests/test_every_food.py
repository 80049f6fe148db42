"""Every shape at every one of the study's five stiffness levels: settles on the plate and
goes through a whole fetch with no NaN, no MuJoCo warning and nothing passing through the
blades or the plate."""

from __future__ import annotations

import pytest

from fetch_env.controller import PHASE_CODE, FetchAction, FetchSimulator
from fetch_env.layouts import SHAPES, single_block
from fetch_env.materials import STUDY_LEVELS, Material, preset
from fetch_env.scene import BLADE_HALF_THICKNESS


@pytest.mark.parametrize("level", STUDY_LEVELS)
@pytest.mark.parametrize("shape", SHAPES)
def test_settles_and_fetches_cleanly(shape: str, level: str) -> None:
    piece = single_block(shape, material=preset(level))[0]
    r = FetchSimulator((piece,)).run("fetch", FetchAction(theta_d=0.045, omega=0.1, hold=0.5))
    tr = r.traces
    assert r.extra["mujoco_warnings"] == {}
    # settled: at rest on the plate when the clamp starts (lowest vertex within 0.5 mm of it)
    settle_end = (tr["phase"] == PHASE_CODE["settle"]).nonzero()[0][-1]
    assert tr["max_log_strain"][settle_end] < 0.01
    p = r.pieces[0]
    # nothing through the plate: the lowest vertex never sinks a millimetre into it
    assert p["lowest_z_ever"] > -1e-3
    # nothing through a blade: no vertex reaches even half-way into one (4 mm thick)
    assert r.extra["max_blade_overlap"] < BLADE_HALF_THICKNESS
    assert not p["passed_through"] and r.extra["passed_through"] == []
    # the outcome is one of the two physical ones: held between the blades, lifted with
    # them, or left on the plate
    if p["fetched"]:
        assert p["final_lowest_z"] > 0.5 * 0.005
    else:
        assert p["final_lowest_z"] < 0.5 * 0.005


@pytest.mark.parametrize(("size", "young", "action"), [
    # the study's very soft level at the env's largest action, and a 50 kPa 20 mm cube (in
    # the Block env's sampled range) at it with the fastest lift
    (0.015, 12300.0, FetchAction(theta_d=0.12, omega=0.4)),
    (0.020, 50000.0, FetchAction(theta_d=0.12, omega=0.4, lift_speed=0.04)),
])
def test_a_piece_squeezed_through_a_blade_is_reported_and_not_fetched(
        size: float, young: float, action: FetchAction) -> None:
    """A very soft piece squeezed hard gets through a blade (a one-cell flex cannot be cut):
    it must be flagged, never counted fetched, and the clean runs above never are."""
    piece = single_block("cube", size=size, material=Material(young=young))[0]
    r = FetchSimulator((piece,)).run("fetch", action)
    p = r.pieces[0]
    assert p["max_blade_overlap"] > 2 * BLADE_HALF_THICKNESS  # measured 32 mm and 6.7 mm
    assert p["passed_through"] and r.extra["passed_through"] == [0]
    assert not p["fetched"] and r.fetch_rate == 0.0
