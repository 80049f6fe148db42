"""K1, K2 and B at the camera's first-contact angle (``ProbeConfig.contact_angle``).

Eq. 7 turns the held moment into a stiffness through ``sin(theta_d) - sin(theta_1)``, and the
probes squeeze a piece only a few per cent of its width past first contact, so a contact
angle a little off moves K1 + K2 by much more.  The depth camera's angle (the piece's rest
surface, from which the clamp angle is set) is the one the truth is defined at
(``fetch_env.probes.elastic_stiffness``); the full fit's, read off the moment's rise, is not.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from fetch_env.errors import InvalidParameterError
from fetch_env.food_space import TUNING_SEED, sample_foods
from fetch_env.probes import (
    CONTACT_ANGLES,
    PROBE_PRESETS,
    ProbeConfig,
    elastic_stiffness,
    run_probes,
)

N_FOODS = 8


def test_contact_angle_is_validated() -> None:
    with pytest.raises(InvalidParameterError, match="contact_angle"):
        ProbeConfig(contact_angle="depth")  # type: ignore[arg-type]
    assert CONTACT_ANGLES == ("fit", "camera")
    assert PROBE_PRESETS["repeated"].contact_angle == "camera"
    # the environments' observations (and Row-v2's "measure" probes) keep the fit's angle
    assert PROBE_PRESETS["env"].contact_angle == "fit"
    assert PROBE_PRESETS["measure"].contact_angle == "fit"


def _stiffness_errors(angle: str) -> tuple[np.ndarray, np.ndarray]:
    """|error| of the uncalibrated K1 + K2 and g1 of the first tuning foods, one clamp."""
    config = dataclasses.replace(PROBE_PRESETS["measure"], contact_angle=angle)
    k_err, g_err = [], []
    for food in sample_foods(N_FOODS, TUNING_SEED):
        piece = food.piece()
        out = run_probes((piece,), config)
        assert out.visco_valid, out.warnings
        k_el = elastic_stiffness(piece, config)["K_el"]
        k_err.append(abs((out.estimates["K1"] + out.estimates["K2"]) / k_el - 1))
        g_err.append(abs(out.estimates["g1"] / food.g1 - 1))
    return np.array(k_err), np.array(g_err)


def test_the_camera_angle_gives_the_stiffness_the_fit_angle_misses() -> None:
    """The first 8 tuning foods (every shape, 0.013-3.4 MPa): K1 + K2 within 0.1-9.6 %
    (median 0.9 %) at the camera's angle, 2.0-21.8 % (median 10 %) at the fit's (measured;
    on 156 tuning foods the medians were 1.2 and 6.9 %).  g1 hardly moves (the angle only
    times the clamp for it): within 0.5 points of the fit angle's error on each food."""
    k_cam, g_cam = _stiffness_errors("camera")
    k_fit, g_fit = _stiffness_errors("fit")
    assert np.median(k_cam) <= 0.02
    assert np.max(k_cam) <= 0.12
    assert np.median(k_fit) >= 0.05
    np.testing.assert_allclose(g_cam, g_fit, atol=0.005)
