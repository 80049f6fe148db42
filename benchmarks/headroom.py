"""Headroom: does each environment separate good agents from poor ones?

For each id, one ``food-fetch evaluate`` run of random, study, model-based and search on the
same seeded scenes (``reset(seed=S + i)``, i < N), and the orderings a benchmark needs:

* ``search`` (the per-scene optimum found with the simulator) beats ``study`` (the study's
  one fixed action) by at least ``--margin`` (0.1) in mean reward, with non-overlapping 95 %
  intervals: a fixed action is not near the best, so there is something to learn;
* ``model-based`` beats ``random`` and ``study`` with non-overlapping intervals: the
  observations carry what a good action needs;
* model-based's regret against search (per scene, paired: the same scenes) with its 95 %
  interval: how much a better agent could still gain.

Reporting seeds start at 80000 (nothing in the project was tuned on them; the -v1 rewards and
the agents' time-cost rules were designed on Block-v1, Row-v1 and Diced-v1 seeds 100-139).
Results are written after each id (atomically), so a stopped run keeps the ids it finished;
with ``--logs DIR`` it also keeps each id's finished episodes and continues them when rerun::

    python benchmarks/headroom.py --ids FoodFetch-Block-v1 --episodes 200 --seed 80000 \\
        --workers 2 --out docs/data/headroom.json --logs headroom_logs
"""

from __future__ import annotations

import argparse
import json
import math
import re
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np
from scipy import stats

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks.readme_meta import meta, write_json
from fetch_env.parallel import raise_interrupt

AGENTS = ("random", "study", "model-based", "search")


def run_evaluate(env_id: str, episodes: int, seed: int, workers: int,
                 logs: Path | None = None) -> tuple[dict, str]:
    """One ``food-fetch evaluate`` run with every episode's record, and its command.

    With ``logs``, the run's episode log is ``logs/ENV_ID.episodes.jsonl``: each finished
    episode is kept there as it finishes, and a log left by a stopped run is continued
    (``--resume``) instead of started over.
    """
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "eval.json"
        cmd = ["food-fetch", "evaluate", "--env", env_id, "--episodes", str(episodes),
               "--seed", str(seed), "--workers", str(workers), "--quiet", "--json-episodes",
               "--json", str(out)]
        cmd += [a for agent in AGENTS for a in ("--agent", agent)]
        extra: list[str] = []
        if logs is not None:
            logs.mkdir(parents=True, exist_ok=True)
            log = logs / f"{env_id}.episodes.jsonl"
            extra = ["--resume", str(log)] if log.exists() else ["--episodes-log", str(log)]
        _run_to_end(cmd + extra)
        data = json.loads(out.read_text())
    shown = " ".join(c if c != str(out) else "FILE" for c in cmd)
    return data, shown


class StoppedError(RuntimeError):
    """The evaluation stopped before its end; ``exit_code``: 130 for a signal, 1 for a
    failed command."""

    def __init__(self, why: str, exit_code: int) -> None:
        super().__init__(why)
        self.exit_code = exit_code


def _run_to_end(cmd: list[str]) -> None:
    """Run ``cmd``; a stop of this process (Ctrl-C, SIGTERM, SIGHUP) is passed on to it, so
    that it writes what finished, and raised as :class:`StoppedError`, as is its failure."""
    child = subprocess.Popen(cmd)
    try:
        code = child.wait()
    except KeyboardInterrupt:
        child.send_signal(signal.SIGTERM)
        child.wait()
        raise StoppedError("stopped", 130) from None
    if code != 0:
        raise StoppedError(f"food-fetch evaluate exited with code {code}", 1)


def paired_difference(a: list[float], b: list[float], level: float = 0.95) -> dict[str, Any]:
    """Mean of ``a - b`` over the same scenes with its t interval."""
    d = np.asarray(a, float) - np.asarray(b, float)
    n = len(d)
    mean = float(d.mean())
    if n < 2:
        return {"mean": mean, "ci95": None, "n": n}
    half = float(stats.t.ppf(0.5 + level / 2, n - 1) * d.std(ddof=1) / math.sqrt(n))
    return {"mean": mean, "ci95": [mean - half, mean + half], "n": n}


def rewards_by_agent(records: list[dict[str, Any]]) -> dict[str, list[float]]:
    """Each agent's rewards in episode order (records come in any order)."""
    out: dict[str, list[tuple[int, float]]] = {}
    for r in records:
        out.setdefault(r["agent"], []).append((r["episode"], float(r["reward"])))
    return {k: [x for _, x in sorted(v)] for k, v in out.items()}


def orderings(agents: dict[str, Any], margin: float) -> dict[str, bool]:
    """The headroom checks on the agents' means and 95 % intervals."""
    def mean(a: str) -> float:
        return float(agents[a]["reward_mean"])

    def lo(a: str) -> float:
        return float(agents[a]["reward_ci95"][0])

    def hi(a: str) -> float:
        return float(agents[a]["reward_ci95"][1])

    return {
        "search_beats_study_by_margin": mean("search") - mean("study") >= margin,
        "search_study_intervals_apart": lo("search") > hi("study"),
        "model_based_above_random": lo("model-based") > hi("random"),
        "model_based_above_study": lo("model-based") > hi("study"),
    }


def headroom(env_id: str, episodes: int, seed: int, workers: int, margin: float,
             logs: Path | None = None) -> dict:
    """One id's agents, orderings and model-based's paired regret against search."""
    data, command = run_evaluate(env_id, episodes, seed, workers, logs)
    keep = ("episodes", "reward_mean", "reward_ci95", "fetch_rate_mean", "success_rate",
            "max_log_strain_mean")
    agents = {a: {k: data["agents"][a][k] for k in keep} for a in AGENTS}
    rewards = rewards_by_agent(data["episodes_detail"])
    checks = orderings(agents, margin)
    return {"command": command, "wall_s": data["wall_time_s"], "agents": agents,
            "regret_model_based": paired_difference(rewards["search"], rewards["model-based"]),
            "search_minus_study": paired_difference(rewards["search"], rewards["study"]),
            "checks": checks, "all_hold": all(checks.values())}


def _keep_added_agents(before: dict[str, Any], after: dict[str, Any]) -> None:
    """Carry the agents added beside the baselines (trained models, the size-only ablation)
    into a rerun of the same scenes; their paired differences to model-based hold only while
    model-based scores what it did, so on other scenes or another model-based they are left
    out, with a note."""
    added = [a for key in ("trained", "ablations") for a in before.get(key, {})]
    if not added:
        return

    def scenes(r: dict[str, Any]) -> str:  # the command less its worker count
        return re.sub(r"--workers \d+ ", "", str(r.get("command")))

    def model_based(r: dict[str, Any]) -> object:
        return r.get("agents", {}).get("model-based", {}).get("reward_mean")

    if scenes(before) != scenes(after) or model_based(before) != model_based(after):
        print(f"note: {', '.join(added)} were measured on other scenes or against another "
              "model-based and are left out; rerun them", flush=True)
        return
    for key in ("trained", "ablations"):
        if key in before:
            after[key] = before[key]
            for agent in before[key]:
                after["agents"][agent] = before["agents"][agent]


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--ids", nargs="+", required=True)
    p.add_argument("--episodes", type=int, default=200)
    p.add_argument("--seed", type=int, default=80000)
    p.add_argument("--workers", type=int, default=2)
    p.add_argument("--margin", type=float, default=0.1)
    p.add_argument("--out", type=Path, default=Path("docs/data/headroom.json"))
    p.add_argument("--logs", type=Path, default=None, metavar="DIR",
                   help="keep each id's episode log in DIR and continue it if a stopped "
                   "run left one (default: none kept)")
    args = p.parse_args()
    for sig in (signal.SIGTERM, signal.SIGHUP):
        signal.signal(sig, raise_interrupt)
    old = json.loads(args.out.read_text()) if args.out.exists() else {}
    results = dict(old.get("results", {}))
    for env_id in args.ids:
        start = time.perf_counter()
        before = results.get(env_id, {})
        try:
            results[env_id] = headroom(env_id, args.episodes, args.seed, args.workers,
                                       args.margin, args.logs)
        except StoppedError as exc:
            kept = (f"its finished episodes are in {args.logs / (env_id + '.episodes.jsonl')} "
                    "(rerun with the same --logs to continue)" if args.logs is not None
                    else "its episodes are lost (--logs DIR keeps them)")
            print(f"headroom: {env_id} {exc}; the ids finished before it are in {args.out}; "
                  f"{kept}", file=sys.stderr)
            return exc.exit_code
        results[env_id]["meta"] = {**meta(), "wall_s": round(time.perf_counter() - start, 1)}
        _keep_added_agents(before, results[env_id])
        write_json(args.out, {"margin": args.margin, "results": results})
        r = results[env_id]
        print(f"{env_id}: all orderings hold: {r['all_hold']} ({r['checks']}); "
              f"regret {r['regret_model_based']['mean']:.3f}", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
