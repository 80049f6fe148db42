"""The probes' calibration fitted on the environments' Block scenes: what it was fitted on,
which environments apply it, and that it measures held-back Block scenes better than the
food space's calibration (a reduced version of tests/test_env_slow.py's Block bars)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from fetch_env.env import FoodFetchEnv
from fetch_env.env_scenes import BLOCK_CALIBRATION_SEED, block_foods, sample_scene
from fetch_env.errors import InvalidParameterError
from fetch_env.probes import (
    PROBE_CALIBRATIONS,
    calibration_for,
    scene_calibration_key,
)

ROOT = Path(__file__).resolve().parents[1]
BLOCK_KEY = scene_calibration_key("measure", "block", "study")
# Held-back Block scenes (tests/test_env_slow.HELD_BACK's first 12): never fitted on.
SEEDS = range(90_000, 90_012)


def test_the_block_calibration_is_fitted_on_block_scenes_only() -> None:
    cal = PROBE_CALIBRATIONS[BLOCK_KEY]
    assert f"block set, seed {BLOCK_CALIBRATION_SEED}, 256 foods" in cal.source
    assert cal.error_model is not None and cal.n_foods == 256
    assert BLOCK_CALIBRATION_SEED > max(SEEDS) + 1000  # disjoint from the held-back seeds


def test_block_foods_are_the_pieces_the_env_draws() -> None:
    foods = block_foods(3)
    for f in foods:
        (p,) = sample_scene("block", np.random.default_rng(BLOCK_CALIBRATION_SEED + f.index))
        assert (f.shape, f.size, f.young, f.g1, f.tau1, f.mu) == (
            p.shape, p.size, p.material.young, p.material.g1, p.material.tau1, p.material.mu)
    assert block_foods(3) == foods
    with pytest.raises(InvalidParameterError, match="n"):
        block_foods(0)
    with pytest.raises(InvalidParameterError, match="seed"):
        block_foods(2, seed=-1)


@pytest.mark.parametrize(("probes", "layout", "scenes", "key"), [
    ("measure", "block", "study", BLOCK_KEY),
    ("measure", "block", "wide", "measure"),  # wide Block scenes are the food space
    ("measure", "row", "study", "measure"),
    ("env", "block", "study", "env"),  # the -v0 ids' default probes keep theirs
    ("repeated", "block", "study", "repeated"),
])
def test_calibration_for_picks_the_scene_space_one_only_where_shipped(
        probes: str, layout: str, scenes: str, key: str) -> None:
    assert calibration_for(probes, layout, scenes) is PROBE_CALIBRATIONS[key]
    env = FoodFetchEnv(layout=layout, probes=probes, scenes=scenes, estimator="model")
    assert env.probe_calibration is PROBE_CALIBRATIONS[key]
    assert calibration_for(probes) is PROBE_CALIBRATIONS[probes]


def test_changed_probe_settings_get_no_calibration() -> None:
    env = FoodFetchEnv(layout="block", probes="measure", estimator="model", probe_hold=15.0)
    assert env.probe_calibration is None


def _errors(env: FoodFetchEnv) -> dict[str, np.ndarray]:
    errs: dict[str, list[float]] = {k: [] for k in ("g1", "tau1", "mu")}
    for seed in SEEDS:
        _, info = env.reset(seed=seed)
        for k in errs:
            errs[k].append(info["estimated_params"][k] / info["true_params"][k] - 1)
    return {k: np.abs(np.array(v)) for k, v in errs.items()}


def test_block_calibration_measures_held_back_block_scenes() -> None:
    """On 12 held-back Block scenes (committed run, docs/data/validation/
    env_estimates.json): with the Block calibration g1 / tau1 / mu median 0.59 / 1.10 / 0.01
    % (max 3.5 / 6.5 / 2.4 %); with the food space's tau1's median was 2.02 %.  Bars: the
    issue's 2 % median and 10 % worst case, and tau1's median below the food space's."""
    env = FoodFetchEnv(layout="block", probes="measure", estimator="model")
    own = _errors(env)
    env.probe_calibration = PROBE_CALIBRATIONS["measure"]
    food_space = _errors(env)
    for k, e in own.items():
        assert np.isfinite(e).all(), f"{k}: {e}"
        assert np.median(e) <= 0.02 and e.max() <= 0.10, f"{k}: {e}"
    assert np.median(own["tau1"]) < np.median(food_space["tau1"]) - 0.005
    assert env.probe_calibration is PROBE_CALIBRATIONS["measure"]


def test_the_block_set_refuses_a_calibrated_run() -> None:
    out = subprocess.run([sys.executable, "benchmarks/validate_estimators.py", "--set",
                          "block", "--n", "2", "--preset", "measure"], cwd=ROOT,
                         capture_output=True, text=True, timeout=120)
    assert out.returncode == 2 and "--no-calibration" in out.stderr
