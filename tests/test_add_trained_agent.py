"""scripts/add_trained_agent.py pairs a learned agent with model-based's episodes only."""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path

import pytest

PATH = Path(__file__).resolve().parents[1] / "scripts" / "add_trained_agent.py"
spec = importlib.util.spec_from_file_location("add_trained_agent", PATH)
assert spec is not None and spec.loader is not None
script = importlib.util.module_from_spec(spec)
spec.loader.exec_module(script)


def _log(path: Path, rows: list[dict]) -> Path:
    head = {"format": "food-fetch evaluate episodes", "format_version": 1}
    path.write_text("\n".join(json.dumps(r) for r in [head, *rows]) + "\n")
    return path


def test_a_log_of_several_agents_gives_model_based_rewards(tmp_path: Path) -> None:
    rows = [{"agent": a, "seed": s, "reward": r}
            for s in (1, 2) for a, r in (("study", 0.5 + s), ("model-based", 0.1 * s))]
    log = _log(tmp_path / "all.jsonl", rows)
    assert script._rewards(log, agent="model-based") == {1: 0.1, 2: 0.2}
    with pytest.raises(SystemExit, match="more than once"):
        script._rewards(log)


def test_paired_difference_uses_the_common_scenes(tmp_path: Path) -> None:
    agent = _log(tmp_path / "a.jsonl", [{"agent": "m.zip", "seed": s, "reward": 1.0}
                                        for s in (1, 2, 3)])
    base = _log(tmp_path / "b.jsonl", [{"agent": "model-based", "seed": s, "reward": 0.5}
                                       for s in (2, 3)])
    out = script._paired(agent, base)
    assert out["n"] == 2 and out["mean"] == pytest.approx(0.5, abs=1e-12)


def test_the_fetches_trained_come_from_the_model_not_the_budget(tmp_path: Path) -> None:
    """A run stopped at step 1886 of a 2000-step budget reports 1886, read from a model
    Stable-Baselines3 itself saved."""
    sb3 = pytest.importorskip("stable_baselines3")
    model = sb3.PPO("MlpPolicy", "Pendulum-v1", n_steps=64, batch_size=64, seed=0)
    model.num_timesteps = 1886
    model.save(tmp_path / "model.zip")
    assert script.trained_timesteps(tmp_path / "model.zip") == 1886
