"""Repeated relaxation clamps (``ProbeConfig.relaxation_repeats``): their squeezes, how their
estimates are combined, and the settings' checks."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from numpy.testing import assert_allclose

from fetch_env.errors import InvalidParameterError
from fetch_env.food_space import Food
from fetch_env.probes import (
    PROBE_CALIBRATIONS,
    PROBE_PRESETS,
    ProbeConfig,
    repeat_strains,
    run_probes,
)
from fetch_env.probes.relaxation import _ClampFit, _median_of_clamps


def test_squeezes_alternate_around_the_set_strain() -> None:
    config = ProbeConfig(strain=0.05, relaxation_repeats=5, repeat_strain_step=0.02)
    assert_allclose(repeat_strains(config), [0.05, 0.049, 0.051, 0.048, 0.052], rtol=1e-12)
    assert repeat_strains(ProbeConfig()) == [ProbeConfig().strain]
    assert repeat_strains(PROBE_PRESETS["repeated"])[0] == PROBE_PRESETS["measure"].strain


@pytest.mark.parametrize(("kwargs", "name"), [
    ({"relaxation_repeats": 0}, "relaxation_repeats"),
    ({"relaxation_repeats": 16}, "relaxation_repeats"),
    ({"relaxation_repeats": True}, "relaxation_repeats"),
    ({"relaxation_repeats": 2.0}, "relaxation_repeats"),
    ({"repeat_strain_step": -0.01}, "repeat_strain_step"),
    ({"repeat_strain_step": math.nan}, "repeat_strain_step"),
    ({"relaxation_repeats": 15, "repeat_strain_step": 0.15}, "repeat_strain_step"),
])
def test_bad_repeat_settings_name_the_value(kwargs: dict[str, object], name: str) -> None:
    with pytest.raises(InvalidParameterError, match=name):
        ProbeConfig(**kwargs)  # type: ignore[arg-type]


def _fit(k: float, g1: float, tau1: float, full: bool, drift: float = 0.1) -> _ClampFit:
    k2 = g1 * k
    values = {"K1": k - k2, "K2": k2, "B": tau1 * k2, "g1": g1, "tau1": tau1}
    if not full:  # a repeated clamp's: values and its hold's drift pair only
        return _ClampFit(values, [], {}, {"drift_log_g1": drift, "drift_log_tau1": drift})
    return _ClampFit(values, ["w"], {n: (0.9 * v, 1.1 * v) for n, v in values.items()},
                     {"drift_log_g1": drift, "drift_log_tau1": drift, "end_drift": 0.5})


def test_median_of_clamps_is_one_consistent_sls() -> None:
    fits = [_fit(1100.0, 0.40, 2.6, True, 0.1), _fit(1000.0, 0.30, 2.0, False, 0.2),
            _fit(900.0, 0.35, 1.8, False, 0.6)]
    out = _median_of_clamps(fits)
    v = out.values
    # g1 and tau1 the clamps' medians, K1 + K2 the first (set-squeeze) clamp's
    assert_allclose([v["K1"] + v["K2"], v["g1"], v["tau1"]], [1100.0, 0.35, 2.0], rtol=1e-12)
    assert_allclose([v["K2"] / (v["K1"] + v["K2"]), v["B"] / v["K2"]], [0.35, 2.0], rtol=1e-12)
    # the first (full) clamp's intervals, moved with the median: +-10 % here
    for name, (lo, hi) in out.intervals.items():
        assert_allclose([lo / v[name], hi / v[name]], [0.9, 1.1], rtol=1e-9, err_msg=name)
    # the drift pair is every clamp's mean, the rest the first clamp's
    assert out.diagnostics["drift_log_tau1"] == pytest.approx(0.3)
    assert out.diagnostics["drift_log_g1"] == pytest.approx(0.3)
    assert out.diagnostics["end_drift"] == 0.5
    assert out.diagnostics["repeat_sd_log_tau1"] == pytest.approx(
        float(np.std(np.log([2.6, 2.0, 1.8]), ddof=1)), rel=1e-12)
    assert out.warnings == ["w"]
    assert _median_of_clamps(fits[:1]) is fits[0]


def test_three_clamps_on_the_study_cube_recover_its_relaxation() -> None:
    """The study's 15 mm, 0.2 MPa cube: three clamps, the preset's calibration, g1 and tau1
    within 5 % of the material's.  (One clamp reproduces the committed `measure` runs:
    tests/test_validation_harness.py.)"""
    food = Food(index=0, shape="cube", size=0.015, young=0.2e6, g1=0.425, tau1=3.667, mu=0.3,
                poisson=0.3, density=1000.0)
    pieces = (food.piece(),)
    three = run_probes(pieces, dataclasses.replace(PROBE_PRESETS["repeated"],
                                                   relaxation_repeats=3),
                       calibration=PROBE_CALIBRATIONS["repeated"])
    assert three.visco_valid
    assert three.estimates["g1"] == pytest.approx(0.425, rel=0.05)
    assert three.estimates["tau1"] == pytest.approx(3.667, rel=0.05)
    assert "repeat_sd_log_tau1" in three.details["diagnostics"]


def test_estimate_cli_runs_the_repeated_probes(tmp_path, capsys: pytest.CaptureFixture[str]
                                               ) -> None:
    """``food-fetch estimate --probes repeated``: the preset's seven clamps and calibration,
    the study's cube measured within 5 %; a study-probe option with it is one line, exit 2."""
    import json

    from tests.cli_helpers import assert_one_line_error, run_cli

    out = tmp_path / "e.json"
    code, _, err = run_cli(["estimate", "--probes", "repeated", "--json", str(out)], capsys)
    assert code == 0, err
    r = json.loads(out.read_text())
    settings = r["details"]["settings"]
    assert settings["probes"] == "repeated" and settings["config"]["relaxation_repeats"] == 7
    for name in ("g1", "tau1", "mu"):
        assert r["estimate"][name] == pytest.approx(r["true"][name], rel=0.05), name
    code, _, err = run_cli(["estimate", "--probes", "repeated", "--hold", "8"], capsys)
    assert_one_line_error(code, err)
    assert "--probes repeated" in err
