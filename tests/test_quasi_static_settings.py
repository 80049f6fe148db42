"""Each id's quasi-static setting (fetch_env.quasi_static) against the committed runs it
was chosen on and reported on, and ``food-fetch evaluate --quasi-static``."""

from __future__ import annotations

import json
import subprocess
import sys

import gymnasium as gym
import pytest

import fetch_env
from benchmarks import bench_quasi_static as bq
from fetch_env.errors import InvalidParameterError
from fetch_env.quasi_static import QUASI_STATIC, QUASI_STATIC_DEFAULT, quasi_static_kwargs


def test_each_setting_is_the_one_its_committed_runs_give() -> None:
    """QUASI_STATIC holds, for every id measured, the fastest candidate at the chaos floor
    on its tuning scenes where it stayed there on the reporting scenes, else the default:
    recomputed from the committed JSON, so a changed rule, file or constant fails here."""
    settings = bq.id_settings()
    assert set(settings) == set(QUASI_STATIC)
    for env_id, r in settings.items():
        assert QUASI_STATIC[env_id] == bq.run_kwargs(r["kept"]), env_id
    assert bq.run_kwargs(bq.FALLBACK) == QUASI_STATIC_DEFAULT


def test_every_kept_setting_is_at_the_floor_on_both_sets() -> None:
    for env_id, r in bq.id_settings().items():
        for which in ("tuning", "reporting"):
            s = r[which]
            assert s[r["kept"]]["pieces_as_reference"] >= s["twin"]["pieces_as_reference"] - 1, (
                env_id, which)
            assert s[r["kept"]]["reward_falls"] <= s["twin"]["reward_falls"] + 1, (env_id, which)


def test_a_setting_that_fails_on_the_reporting_scenes_is_not_kept() -> None:
    def run(pieces: int, falls: int = 0, speedup: float = 1.0) -> dict[str, float]:
        return {"pieces_as_reference": pieces, "reward_falls": falls, "episode_speedup": speedup,
                "errors": 0}

    tuning = {"twin": run(10, 1), "x5c0.1": run(10, 0, 1.5), "x5c0.4": run(9, 2, 2.0)}
    reporting = {"twin": run(20, 1), "x5c0.1": run(20), "x5c0.4": run(18)}
    assert bq.fastest_at_floor(tuning, ("x5c0.1", "x5c0.4")) == "x5c0.4"
    assert bq.validated_setting(tuning, reporting, ("x5c0.1", "x5c0.4"), "x5c0.1") == "x5c0.1"
    reporting["x5c0.4"]["pieces_as_reference"] = 19
    assert bq.validated_setting(tuning, reporting, ("x5c0.1", "x5c0.4"), "x5c0.1") == "x5c0.4"
    reporting["x5c0.4"]["reward_falls"] = 3  # crushes more than chance does
    assert bq.validated_setting(tuning, reporting, ("x5c0.1", "x5c0.4"), "x5c0.1") == "x5c0.1"
    tuning["x5c0.4"]["reward_falls"] = 3
    assert bq.fastest_at_floor(tuning, ("x5c0.1", "x5c0.4")) == "x5c0.1"
    tuning["x5c0.1"]["errors"] = 1  # a fetch that failed where the twin's did not
    assert bq.fastest_at_floor(tuning, ("x5c0.1", "x5c0.4")) is None
    tuning["x5c0.1"]["errors"] = 0
    reporting["x5c0.1"]["pieces_as_reference"] = reporting["x5c0.4"]["pieces_as_reference"] = 5
    with pytest.raises(ValueError, match="fallback"):
        bq.validated_setting(tuning, reporting, ("x5c0.1", "x5c0.4"), "x5c0.1")
    del reporting["x5c0.1"]
    with pytest.raises(ValueError, match="reporting runs have no"):
        bq.validated_setting(tuning, reporting, ("x5c0.1", "x5c0.4"), "x5c0.1")


@pytest.mark.parametrize("env_id", sorted(fetch_env.ENV_IDS))
def test_every_id_has_a_setting_its_env_accepts(env_id: str) -> None:
    kwargs = quasi_static_kwargs(env_id)
    assert kwargs == QUASI_STATIC.get(env_id, QUASI_STATIC_DEFAULT)
    env = gym.make(env_id, **kwargs)
    assert env.unwrapped.fetch_hold_scale == kwargs["fetch_hold_scale"]
    assert env.unwrapped.fetch_clamp_speed == kwargs["fetch_clamp_speed"]
    env.close()


def test_an_unknown_id_is_refused_by_name() -> None:
    with pytest.raises(InvalidParameterError, match="FoodFetch-Block-v9"):
        quasi_static_kwargs("FoodFetch-Block-v9")


def test_evaluate_quasi_static_applies_the_ids_setting(tmp_path) -> None:
    """One episode each way: --quasi-static puts the id's setting into the env kwargs (the
    JSON and the header say so), and an --env-kwargs value overrides its part."""
    out = tmp_path / "qs.json"
    assert QUASI_STATIC["FoodFetch-Block-v1"]["fetch_clamp_speed"] != 0.1
    cmd = [sys.executable, "-m", "agents.cli", "evaluate", "--env", "FoodFetch-Block-v1",
           "--agent", "study", "--episodes", "1", "--seed", "7", "--quasi-static",
           "--env-kwargs", "fetch_clamp_speed=0.1", "--json", str(out), "--quiet"]
    res = subprocess.run(cmd, capture_output=True, text=True, timeout=300)
    assert res.returncode == 0, res.stderr
    assert json.loads(out.read_text())["env_kwargs"] == {"fetch_hold_scale": 5.0,
                                                         "fetch_clamp_speed": 0.1}
    assert "fetch_hold_scale=5.0, fetch_clamp_speed=0.1" in res.stdout.splitlines()[0]


def test_the_pages_tables_are_the_committed_runs() -> None:
    """The page's two tables of each id's setting are what --ids-page writes from the
    committed runs (a changed file or rule that was not written to the page fails here)."""
    text = bq.PAGE.read_text()
    assert bq.settings_page(bq.id_settings()) in text
    for path in (*bq.ID_TUNING[1:], *bq.ID_REPORTING):
        assert bq.page(json.loads(path.read_text())) in text
