"""The roll toward the mouth (fetch_env.carry): statics of the rotated weight, a grip inside
Coulomb's limit along the hinge axis, and a fetch without the roll unchanged."""

from __future__ import annotations

import math

import numpy as np
import pytest

from fetch_env.carry import tilt_angles
from fetch_env.controller import PHASE_CODE, FetchAction, FetchSimulator
from fetch_env.errors import InvalidParameterError
from fetch_env.layouts import single_block

TILT = 1.0  # [rad]
RAMP = 0.4  # [s]


@pytest.fixture(scope="module")
def rolled():
    """The study's cube clamped at the lightest touch that holds it, lifted, rolled by 1 rad."""
    sim = FetchSimulator(single_block())
    action = FetchAction(theta_d=0.03, omega=0.4, lift_speed=0.04, hold=0.5, air_hold=1.0,
                         tilt=TILT, tilt_ramp=RAMP)
    return sim.run("fetch", action), sim.run("fetch", FetchAction(
        theta_d=0.03, omega=0.4, lift_speed=0.04, hold=0.5, air_hold=1.0))


def test_the_ramp_is_half_a_cosine_then_held() -> None:
    phi = tilt_angles(np.array([0.0, 0.2, 0.4, 0.9]), 1.0, 0.4)
    np.testing.assert_allclose(phi, [0.0, 0.5, 1.0, 1.0], atol=1e-12)


def test_the_end_effector_carries_the_rotated_weight(rolled) -> None:
    """Statics in the pair's frame: once rolled, the blades carry m g sin(phi) along the hinge
    axis and m g cos(phi) downward.  Measured: both within 0.3 % over the last 0.5 s."""
    r, _ = rolled
    assert r.fetch_rate == 1.0 and r.extra["tilt_loaded"] == [0]
    weight = single_block()[0].mass * 9.81
    tr = r.traces
    air = np.flatnonzero(tr["phase"] == PHASE_CODE["air"])
    late = air[tr["t"][air] >= tr["t"][air[0]] + RAMP + 0.1]
    assert late.size >= 40
    fx, fz = tr["force"][late, 0], tr["force"][late, 2]
    # the food pushes the blades along +x (the rotated weight) and down
    np.testing.assert_allclose(fx.mean(), weight * math.sin(TILT), rtol=0.01)
    np.testing.assert_allclose(fz.mean(), -weight * math.cos(TILT), rtol=0.01)


def test_a_grip_well_inside_coulomb_s_limit_does_not_slide(rolled) -> None:
    """2 mu N far above m g sin(phi): the piece stays where the lift left it along the hinge
    axis (measured: 0.01 mm), and the friction the faces carry is the load, not mu N."""
    r, unrolled = rolled
    moved = r.pieces[0]["final_centre"][0] - unrolled.pieces[0]["final_centre"][0]
    assert abs(moved) < 1e-4  # m
    tr = r.traces
    late = np.flatnonzero(tr["phase"] == PHASE_CODE["air"])[-20:]
    normal = 0.5 * (np.abs(tr["normal_left"][late]) + np.abs(tr["normal_right"][late]))
    mu = single_block()[0].material.mu
    assert (2 * mu * normal).min() > 3 * single_block()[0].mass * 9.81 * math.sin(TILT)


def test_rolled_the_faces_friction_carries_the_weight_the_wedge_carried() -> None:
    """Unrolled, the V's slope carries part of the weight through the faces' normal force
    (at 0.03 rad on the study's cube, measured: the faces' friction carries 0.59 m g, the
    wedge the rest); rolled to pi/2 the weight lies along the hinge axis, which the V does
    not wedge, so friction alone holds it: the force along x (which has no part in a face's
    normal) is the whole weight."""
    sim = FetchSimulator(single_block())
    weight = single_block()[0].mass * 9.81
    base = dict(theta_d=0.03, omega=0.4, lift_speed=0.04, hold=0.5, air_hold=1.0)
    for tilt, along_x in ((0.0, 0.0), (0.5 * math.pi, 1.0)):
        r = sim.run("fetch", FetchAction(**base, tilt=tilt))
        tr = r.traces
        late = np.flatnonzero(tr["phase"] == PHASE_CODE["air"])[-20:]
        np.testing.assert_allclose(tr["force"][late, 0].mean() / weight, along_x, atol=0.01)
        np.testing.assert_allclose(tr["force"][late, 2].mean() / weight, along_x - 1.0,
                                   atol=0.01)
        assert r.fetch_rate == 1.0


def test_no_roll_leaves_the_fetch_and_its_record_as_they_were() -> None:
    action = FetchAction(theta_d=0.045, hold=0.5)
    assert "tilt" not in action.to_dict()
    r = FetchSimulator(single_block()).run("fetch", action)
    assert "tilt_loaded" not in r.extra


@pytest.mark.parametrize("field,value", [("tilt", -0.1), ("tilt", 2.0), ("tilt", math.nan),
                                         ("tilt_ramp", 0.0), ("tilt_ramp", 11.0)])
def test_bad_roll_is_refused_by_name(field: str, value: float) -> None:
    with pytest.raises(InvalidParameterError, match=field):
        FetchAction(**{field: value})
