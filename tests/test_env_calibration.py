"""The environments' model estimates are calibrated by default (probe_calibrated)."""

from __future__ import annotations

import pytest
from numpy.testing import assert_allclose

from fetch_env.env import FoodFetchEnv
from fetch_env.errors import InvalidParameterError


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
