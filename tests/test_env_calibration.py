"""The environments' model estimates are calibrated by default (probe_calibrated)."""

from __future__ import annotations

import pytest
from numpy.testing import assert_allclose

from fetch_env.env import FoodFetchEnv
from fetch_env.errors import InvalidParameterError
from fetch_env.probes import PROBE_PRESETS


def test_calibration_is_applied_by_default_and_can_be_turned_off() -> None:
    on = FoodFetchEnv(layout="block", estimator="model")
    off = FoodFetchEnv(layout="block", estimator="model", probe_calibrated=False)
    _, info_on = on.reset(seed=90_000)
    _, info_off = off.reset(seed=90_000)
    assert "tuning set, seed 1000" in info_on["probe_calibration"]
    assert info_off["probe_calibration"] is None
    est_on, est_off = info_on["estimated_params"], info_off["estimated_params"]
    assert est_on["mu"] == est_off["mu"]  # mu is not corrected
    assert est_on["tau1"] != est_off["tau1"]
    # the corrected K1, K2, B stay one SLS with the corrected g1 and tau1
    assert_allclose(est_on["K2"] / (est_on["K1"] + est_on["K2"]), est_on["g1"], rtol=1e-9)
    assert_allclose(est_on["B"] / est_on["K2"], est_on["tau1"], rtol=1e-9)


def test_non_default_probes_run_uncalibrated_and_say_so() -> None:
    env = FoodFetchEnv(layout="block", estimator="model", probe_hold=3.0)
    _, info = env.reset(seed=90_001)
    assert info["probe_calibration"] is None


def test_probe_calibrated_must_be_a_bool() -> None:
    with pytest.raises(InvalidParameterError, match="probe_calibrated"):
        FoodFetchEnv(probe_calibrated="yes")  # type: ignore[arg-type]


def test_measure_probes_run_the_estimate_presets_probes_with_their_own_calibration() -> None:
    env = FoodFetchEnv(layout="block", estimator="model", probes="measure")
    assert env.probe_config == PROBE_PRESETS["measure"]
    assert env.probe_config.hold == 20.0 and env.probe_config.slide_time == 0.3
    _, info = env.reset(seed=90_000)
    assert "preset measure" in info["probe_calibration"]
    assert "preset env" in FoodFetchEnv(layout="block").probe_calibration.source


def test_a_probe_setting_given_replaces_the_presets_and_drops_its_calibration() -> None:
    env = FoodFetchEnv(layout="block", probes="measure", probe_hold=10.0)
    assert env.probe_config.hold == 10.0
    assert env.probe_config.slide_time == PROBE_PRESETS["measure"].slide_time
    assert env.probe_calibration is None


@pytest.mark.parametrize(("kwargs", "named"), [
    ({"probes": "fast"}, "probes"), ({"probes": None}, "probes"),
    ({"probes": "measure", "probe_hold": 90.0}, "probe_hold"),
    ({"probe_time_scale": 0.5}, "probe_time_scale"), ({"probe_omega": float("nan")}, "probe_omega"),
])
def test_bad_probe_settings_are_refused_by_name(kwargs: dict, named: str) -> None:
    with pytest.raises(InvalidParameterError, match=named):
        FoodFetchEnv(**kwargs)
