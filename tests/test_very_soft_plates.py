"""The softest-level check of benchmarks/very_soft_plates.py: its summary, and the committed
runs' summaries recomputed from their fetches."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from benchmarks.very_soft_plates import SETTINGS, summarize_levels  # noqa: E402


def _row(seed: int, theta: float, rewards: tuple[float, float, float]) -> dict:
    fetches = {name: {"reward": r} for name, r in zip(SETTINGS, rewards, strict=True)}
    return {"seed": seed, "theta": theta, "spread": max(rewards) - min(rewards), **fetches}


def test_summary_counts_the_plates_whose_settings_disagree_by_more_than_half() -> None:
    rows = [_row(1, 0.04, (0.9, 0.9, 0.9)), _row(2, 0.04, (0.9, 0.3, 0.9)),
            _row(1, 0.07, (0.9, -4.1, 0.9)), _row(2, 0.07, (0.9, 0.5, 0.8))]
    out = summarize_levels(rows)
    assert set(out) == {"0.04", "0.07"}
    assert out["0.04"]["settings_disagree"] == 1 and out["0.04"]["fetches"] == 2
    assert out["0.04"]["mean_spread"] == pytest.approx(0.3)
    assert out["0.07"]["settings_disagree"] == 1  # 5.0 apart; 0.4 apart is not counted
    assert out["0.07"]["mean_reward"]["step 2.5 ms"] == pytest.approx(-1.8)


@pytest.mark.parametrize("path", sorted((ROOT / "docs" / "data").glob(
    "very_soft_plates_levels_*.json")), ids=lambda p: p.stem)
def test_committed_summaries_follow_from_their_fetches(path: Path) -> None:
    data = json.loads(path.read_text())
    assert data["fetches"], path.name
    for r in data["fetches"]:
        rewards = [r[name]["reward"] for name in SETTINGS]
        assert r["spread"] == pytest.approx(max(rewards) - min(rewards), abs=1e-9)
    assert data["summary"] == summarize_levels(data["fetches"])
