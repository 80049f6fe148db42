"""The committed soak (docs/data/soak.json, ``benchmarks/soak.py``) covers every registered id
at 1000 episodes in one process and meets the limits a long run must: the median resident
memory of the last tenth of episodes under 20 MiB above that of the second tenth, and the
second tenth's episodes, run again at the end with the same seeds and actions, under 10 %
dearer in CPU time (median of the paired ratios).  The CPU time of the two windows is
recomputed and reported, not limited: they hold different scenes, and a multi-piece id's
episode cost varies twofold with its scene, so their medians differ by up to 18 % with no
slowdown at all (TwoRows-v1: -17.9 % while the rerun episodes cost -4.1 %)."""

from __future__ import annotations

import json
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import fetch_env  # noqa: F401  (registers the ids)

ROOT = Path(__file__).resolve().parents[1]
SOAK = json.loads((ROOT / "docs" / "data" / "soak.json").read_text())
IDS = sorted(k for k in gym.registry if k.startswith("FoodFetch-"))
# Registered ids the committed soak does not hold yet, with why; an id soaked later must
# leave this table (the first test fails until it does).
NOT_SOAKED: dict[str, str] = {}


def test_every_registered_id_was_soaked() -> None:
    assert sorted(SOAK["ids"]) == sorted(set(IDS) - set(NOT_SOAKED))


@pytest.mark.parametrize("env_id", [
    pytest.param(i, marks=pytest.mark.xfail(i in NOT_SOAKED, reason=NOT_SOAKED.get(i, ""),
                                            raises=KeyError, strict=True)) for i in IDS])
def test_the_soak_meets_the_limits(env_id: str) -> None:
    run = SOAK["ids"][env_id]
    s = run["summary"]
    assert run["complete"] and s["episodes"] >= 1000, env_id
    # recomputed from the per-episode readings, windows as the summary names them
    rss, cpu = np.array(run["rss_mib"]), np.array(run["episode_cpu_s"])
    (e0, e1), (l0, l1) = s["early_window"], s["late_window"]
    growth = np.median(rss[l0:l1]) - np.median(rss[e0:e1])
    change = np.median(cpu[l0:l1]) / np.median(cpu[e0:e1]) - 1
    assert growth == pytest.approx(s["rss_growth_mib"], abs=0.02)  # (readings stored to 0.01 MiB)
    assert 100 * change == pytest.approx(s["episode_cpu_change_pct"], abs=0.05)
    assert growth < SOAK["limits"]["rss_growth_mib"]
    # the slowdown check: the same episodes, early against late, paired
    again = run["replay"]
    first = cpu[slice(*again["episodes"])]
    assert (again["episodes"][0], again["episodes"][1]) == (e0, e1)
    slowdown = np.median(np.array(again["cpu_s_again"]) / first) - 1
    assert 100 * slowdown == pytest.approx(again["median_paired_change_pct"], abs=0.05)
    assert slowdown < SOAK["limits"]["episode_time_change"]


def test_a_rerun_keeps_each_kept_id_s_machine_and_stamps_its_own(tmp_path: Path,
                                                                   monkeypatch) -> None:
    """benchmarks/soak.py merges into an existing file: ids not rerun keep the machine and
    command that measured them (from the file's own top level where they had none), and the
    rerun id records this machine and command."""
    import importlib.util
    spec = importlib.util.spec_from_file_location("soak", ROOT / "benchmarks" / "soak.py")
    soak = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(soak)
    out = tmp_path / "soak.json"
    out.write_text(json.dumps({"ids": {"FoodFetch-Block-v0": {"summary": {}}},
                               "machine": {"machine": "x86_64, 2 cores (Old CPU)"},
                               "command": "python benchmarks/soak.py --env FoodFetch-Block-v0"}))

    def fake_soak(env_id, episodes, seed, record, path, data, flush, trim=False):
        record.update(summary={k: 0.0 for k in (
            "rss_median_early_mib", "rss_median_late_mib", "rss_growth_mib", "rss_growth_pct",
            "episode_s_median_early", "episode_s_median_late", "episode_time_change_pct",
            "episode_cpu_s_median_early", "episode_cpu_s_median_late",
            "episode_cpu_change_pct")}, replay={"median_paired_change_pct": 0.0})
        soak.write_atomic(path, data)
        return record

    monkeypatch.setattr(soak, "soak", fake_soak)
    monkeypatch.setattr(soak, "machine", lambda: {"machine": "x86_64, 2 cores (New CPU)"})
    assert soak.main(["--env", "FoodFetch-Row-v0", "--out", str(out)]) == 0
    data = json.loads(out.read_text())
    kept, new = data["ids"]["FoodFetch-Block-v0"], data["ids"]["FoodFetch-Row-v0"]
    assert kept["machine"] == "x86_64, 2 cores (Old CPU)"
    assert kept["command"] == "python benchmarks/soak.py --env FoodFetch-Block-v0"
    assert new["machine"] == data["machine"]["machine"] == "x86_64, 2 cores (New CPU)"
    assert new["command"].endswith("--env FoodFetch-Row-v0 --out " + str(out))
