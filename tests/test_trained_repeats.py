"""The repeated trained-agent evaluations in docs/data/trained/ agree with their own rewards
and with docs/data/headroom.json (the figures docs/agents.md and the CHANGELOG cite)."""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Any

import pytest

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))
from headroom import paired_difference  # noqa: E402

FILES = sorted((ROOT / "docs" / "data" / "trained").glob("*_repeats.json"))
HEADROOM = json.loads((ROOT / "docs" / "data" / "headroom.json").read_text())["results"]
HEADROOM_SCENES = "80000-80199"


def _load(path: Path) -> dict[str, Any]:
    return json.loads(path.read_text())


def _close(stored: dict[str, Any], computed: dict[str, Any]) -> None:
    assert stored["mean"] == pytest.approx(computed["mean"], abs=1e-12)
    assert stored["ci95"] == pytest.approx(computed["ci95"], abs=1e-12)


def test_there_are_repeats() -> None:
    assert {p.name for p in FILES} >= {"FoodFetch-Diced-v1_ppo_repeats.json",
                                        "FoodFetch-Row-v1_sac_repeats.json"}


@pytest.mark.parametrize("path", FILES, ids=lambda p: p.stem)
def test_every_figure_follows_from_the_stored_rewards(path: Path) -> None:
    data = _load(path)
    for run in data["runs"]:
        rewards = run["rewards"]
        base = data["model_based"][run["scenes"]]["rewards"]
        assert len(rewards) == len(base) == 200
        _close(run["reward"], paired_difference(rewards, [0.0] * len(rewards)))
        _close(run["minus_model_based"], paired_difference(rewards, base))
        better = sum(a > b for a, b in zip(rewards, base, strict=True))
        assert run["minus_model_based"]["better"] == better


@pytest.mark.parametrize("path", FILES, ids=lambda p: p.stem)
def test_the_headroom_scenes_are_the_headroom_tables(path: Path) -> None:
    """Model-based's rewards on the headroom scenes are the headroom run's, and the run that
    headroom.json holds for the algorithm is one of the repeats, with the same paired figure."""
    data = _load(path)
    result = HEADROOM[data["env_id"]]
    base = data["model_based"][HEADROOM_SCENES]["rewards"]
    assert sum(base) / len(base) == pytest.approx(
        result["agents"]["model-based"]["reward_mean"], abs=1e-12)
    algo = data["runs"][0]["algo"]
    shipped = result["trained"][algo]["minus_model_based"]
    matches = [r for r in data["runs"] if r["scenes"] == HEADROOM_SCENES
               and r["minus_model_based"]["mean"] == pytest.approx(shipped["mean"], abs=1e-12)]
    assert matches, f"{path.name}: no run matches headroom.json's {algo} figure"
    assert matches[0]["minus_model_based"]["ci95"] == pytest.approx(shipped["ci95"], abs=1e-12)


def test_the_two_seed_mean_on_diced() -> None:
    data = _load(ROOT / "docs" / "data" / "trained" / "FoodFetch-Diced-v1_ppo_repeats.json")
    two = data["two_seeds_mean_minus_model_based"]
    a, b = (data["runs"][i]["rewards"] for i in two["runs"])
    assert {data["runs"][i]["training_seed"] for i in two["runs"]} == {0, 1}
    _close(two, paired_difference([(x + y) / 2 for x, y in zip(a, b, strict=True)],
                                  data["model_based"][HEADROOM_SCENES]["rewards"]))
