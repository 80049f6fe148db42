"""Headroom on the benchmark ids, rerun on scenes the committed table did not use.

``docs/data/headroom.json`` (``benchmarks/headroom.py``, 200 scenes per id from seed 80000) is
the reported table, where the orderings hold with non-overlapping 95 % intervals; this reruns
a 40-scene version from seed 81000 and checks the same orderings of the means there: search
beats study by at least 0.1 (significantly, paired) and model-based beats random and study.
"""

from __future__ import annotations

import importlib.util
import json
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
COMMITTED = json.loads((ROOT / "docs" / "data" / "headroom.json").read_text())


def _headroom_module():
    sys.path.insert(0, str(ROOT))
    spec = importlib.util.spec_from_file_location("headroom", ROOT / "benchmarks" / "headroom.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


# The orderings the committed 200-scene table measured to fail, per id, with why (the README
# and docs/agents.md say so too); a change either way fails the test below, so that it is
# noticed and the text updated.
KNOWN_SHORTFALLS: dict[str, set[str]] = {
    # model-based beats study on most scenes (paired +0.24 [0.11, 0.37] on the 189 scenes
    # its episode log kept), but a fifth of the scenes are 0.0123 MPa plates where every
    # action is a lottery, so both agents' own intervals are wide and overlap
    "FoodFetch-TwoRows-v1": {"model_based_above_study"},
}


def test_the_committed_table_shows_every_ordering_on_each_id_it_measured() -> None:
    for env_id, r in COMMITTED["results"].items():
        assert r["agents"]["search"]["episodes"] >= 200, env_id
        failed = {k for k, ok in r["checks"].items() if not ok}
        assert failed == KNOWN_SHORTFALLS.get(env_id, set()), (env_id, r["checks"])
        assert r["all_hold"] == (not failed), env_id
        assert r["checks"]["search_beats_study_by_margin"], env_id  # the benchmark's headroom
        regret = r["regret_model_based"]
        assert regret["ci95"][0] <= regret["mean"] <= regret["ci95"][1]


def test_paired_difference_is_the_mean_difference_with_a_t_interval() -> None:
    h = _headroom_module()
    out = h.paired_difference([1.0, 2.0, 3.0, 4.0], [0.5, 1.5, 2.0, 3.0])
    assert out["mean"] == pytest.approx(0.75)
    # differences 0.5, 0.5, 1.0, 1.0: sd 0.2887, t(0.975, 3) 3.1824 -> half 0.4594
    assert out["ci95"] == pytest.approx([0.75 - 0.4594, 0.75 + 0.4594], abs=1e-3)
    checks = h.orderings({a: {"reward_mean": m, "reward_ci95": [m - 0.01, m + 0.01]}
                          for a, m in (("random", 0.1), ("study", 0.5),
                                       ("model-based", 0.7), ("search", 0.65))}, 0.1)
    assert checks == {"search_beats_study_by_margin": True,
                      "search_study_intervals_apart": True,
                      "model_based_above_random": True, "model_based_above_study": True}


def test_a_rerun_keeps_added_agents_only_on_the_same_scenes(
        capsys: pytest.CaptureFixture[str]) -> None:
    """Trained and ablation agents survive a rerun of the same scenes (the worker count
    changes nothing), and are dropped with a note when the scenes differ."""
    h = _headroom_module()
    base = "food-fetch evaluate --env E --episodes 200 --seed 80000 --workers 2 --json FILE"
    mb = {"model-based": {"reward_mean": 0.8}}
    before = {"command": base, "agents": {**mb, "sac": {"reward_mean": 0.9}, "size-only": {}},
              "trained": {"sac": {"timesteps": 10}}, "ablations": {"size-only": {}}}
    same = {"command": base.replace("--workers 2", "--workers 1"), "agents": dict(mb)}
    h._keep_added_agents(before, same)
    assert set(same["agents"]) == {"model-based", "sac", "size-only"}
    assert same["trained"] == before["trained"] and same["ablations"] == before["ablations"]
    for other in ({"command": base.replace("--seed 80000", "--seed 81000"), "agents": dict(mb)},
                  {"command": base, "agents": {"model-based": {"reward_mean": 0.85}}}):
        h._keep_added_agents(before, other)
        assert set(other) == {"command", "agents"} and "sac" not in other["agents"]
        assert "sac, size-only were measured on other scenes" in capsys.readouterr().out


@pytest.mark.slow
@pytest.mark.parametrize("env_id", sorted(COMMITTED["results"]))
def test_orderings_hold_on_other_scenes(env_id: str) -> None:
    """40 scenes from seed 81000 (~5 min per Block id on 2 cores): the orderings of the
    means, and search's gain over study significant on the paired scenes (non-overlapping
    intervals of the agents' own rewards are the committed table's, on 200 scenes)."""
    h = _headroom_module()
    r = h.headroom(env_id, episodes=40, seed=81000, workers=2, margin=0.1)
    mean = {a: s["reward_mean"] for a, s in r["agents"].items()}
    print(f"{env_id}, 40 scenes from seed 81000: "  # (shown by pytest -s or -rP)
          + ", ".join(f"{a} {m:.3f}" for a, m in mean.items())
          + f"; search - study {r['search_minus_study']['mean']:.3f} "
          f"{[round(v, 3) for v in r['search_minus_study']['ci95']]}")
    assert mean["search"] - mean["study"] >= 0.1, mean
    assert r["search_minus_study"]["ci95"][0] > 0, r["search_minus_study"]
    if not KNOWN_SHORTFALLS.get(env_id):  # (else its model-based is not expected to order)
        assert mean["model-based"] > max(mean["study"], mean["random"]), mean
