"""benchmarks/squeeze_grid.py: its summary, its choice rule, and the committed grid the
model-based agent's diced squeeze was chosen on."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest

from agents.model_based import ModelBasedConfig

ROOT = Path(__file__).resolve().parents[1]
GRID = ROOT / "docs" / "data" / "tuning" / "FoodFetch-Diced-v1_squeeze_grid.json"


def _module():
    sys.path.insert(0, str(ROOT))
    from benchmarks import squeeze_grid

    return squeeze_grid


def _rows(rewards: dict[float, list[float]]) -> list[dict]:
    n = len(next(iter(rewards.values())))
    return [{"seed": i, "grid": [{"eps": e, "omega": 0.4, "lift_speed": 0.04,
                                  "reward": r[i]} for e, r in rewards.items()],
             "model_based": {"reward": rewards[0.1][i]}, "grip_rule": {"reward": 0.0}}
            for i in range(n)]


def test_the_least_squeeze_not_clearly_worse_than_the_best_is_chosen() -> None:
    m = _module()
    rng = np.random.default_rng(0)
    base = rng.normal(0.0, 0.5, 40)
    rows = _rows({0.05: list(base - 0.3), 0.1: list(base + rng.normal(0, 0.05, 40)),
                  0.2: list(base + 0.02)})
    s = m.summarize(rows)
    by_eps = {a["eps"]: a for a in s["actions"]}
    assert by_eps[0.2]["minus_best"]["ci95"] == [0.0, 0.0]  # 0.2 has the best mean
    assert by_eps[0.05]["minus_best"]["ci95"][1] < 0  # clearly worse
    assert m.least_squeeze_near_best(s, 0.4) == 0.1
    assert s["model_based"]["reward_mean"] == pytest.approx(
        np.mean([r["model_based"]["reward"] for r in rows]))
    assert by_eps[0.05]["crushed_plates"] == int(np.sum(base - 0.3 < -0.3))


def test_the_shipped_diced_squeeze_is_the_committed_grids_choice() -> None:
    """eps_diced is what the rule picks on the committed tuning grid, and the shipped agent
    scored there exactly as the grid's (eps_diced, fastest speeds) column: the same action."""
    data = json.loads(GRID.read_text())
    assert data["env_id"] == "FoodFetch-Diced-v1" and data["seeds"] == "100-299"
    choice = data["summary"]["least_squeeze_near_best"]
    assert choice == {"omega": 0.4, "eps": ModelBasedConfig().eps_diced}
    assert _module().least_squeeze_near_best(data["summary"], 0.4) == choice["eps"]
    for row in data["scenes"]:
        (cell,) = [g for g in row["grid"] if g["eps"] == choice["eps"] and g["omega"] == 0.4]
        assert row["model_based"]["reward"] == cell["reward"], row["seed"]
        assert row["model_based"]["theta_d"] == pytest.approx(cell["theta_d"], abs=1e-9)


@pytest.mark.parametrize("seed", [100, 102, 103])
def test_max_young_filter_sees_the_scene_reset_draws(seed: int) -> None:
    """--max-young picks scenes without running the probes: the stiffest piece it reads is
    the one the probing env's reset(seed) builds (0.0123 MPa, 200 MPa and 40 MPa plates on
    these seeds)."""
    import warnings

    import gymnasium as gym

    env = gym.make("FoodFetch-TwoRows-v1")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        env.reset(seed=seed)
    expected = max(p.material.young for p in env.unwrapped.pieces)
    env.close()
    assert _module().stiffest_young("FoodFetch-TwoRows-v1", seed) == expected
    assert expected == {100: 0.0123e6, 102: 200e6, 103: 40e6}[seed]
