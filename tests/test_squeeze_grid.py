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


SOFT_GRID = ROOT / "docs" / "data" / "tuning" / "FoodFetch-TwoRows-v1_soft_squeeze_grid.json"
SOFT_RULE = ROOT / "docs" / "data" / "tuning" / "FoodFetch-TwoRows-v1_two_rows_soft_modulus.json"


def test_the_shipped_soft_two_rows_squeeze_is_the_soft_grids_choice() -> None:
    """On the very soft two-row tuning plates every squeeze of the grid loses on average and
    the least is chosen: eps_two_rows_soft is the grid's choice at the fast speeds."""
    data = json.loads(SOFT_GRID.read_text())
    assert data["env_id"] == "FoodFetch-TwoRows-v1" and data["seeds"] == "100-299"
    assert data["max_young_mpa"] == 0.02 and data["summary"]["n_scenes"] == 53
    choice = data["summary"]["least_squeeze_near_best"]
    assert choice == {"omega": 0.4, "eps": ModelBasedConfig().eps_two_rows_soft}
    assert all(a["reward_mean"] < 0 for a in data["summary"]["actions"])
    (least,) = [a for a in data["summary"]["actions"] if a["eps"] == 0.04 and a["omega"] == 0.4]
    assert least["reward_mean"] == max(a["reward_mean"] for a in data["summary"]["actions"])


def test_the_soft_two_rows_threshold_separates_the_tuning_plates_by_level() -> None:
    """two_rows_soft_modulus lies above every 0.0123 MPa tuning plate's probed modulus (by
    25 %) and below a third of every stiffer one's, on the scenes with a valid estimate; the
    rule changes those 44 plates only, and gains on them."""
    data = json.loads(SOFT_RULE.read_text())
    assert data["seeds"] == "100-299" and len(data["scenes"]) == 200
    limit = ModelBasedConfig().two_rows_soft_modulus
    valid = [s for s in data["scenes"] if s["visco_valid"]]
    soft = [s["probed_modulus"] for s in valid if s["young"] < 0.02e6]
    firm = [s["probed_modulus"] for s in valid if s["young"] > 0.02e6]
    assert len(soft) == 44 and len(firm) == 133
    assert max(soft) * 1.25 < limit < min(firm) / 3
    old, new = data["runs"]
    assert (old["value"], new["value"]) == (0.0, limit)
    gain = np.array(new["rewards"]) - np.array(old["rewards"])
    assert np.count_nonzero(gain) == 44 and gain.mean() > 0.05
