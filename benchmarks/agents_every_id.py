"""The built-in agents on every environment id: ``food-fetch evaluate`` per id, one JSON.

Runs ``food-fetch evaluate --env ID --agent random --agent study --agent model-based
--episodes N --seed S --workers W`` for each registered id and keeps each run's summary
(mean reward, fetch rate, success rate, max LE, with 95 % intervals) in one file, with the
machine and the command, for the README's agents table (``scripts/make_readme_tables.py``).

The scenes are reporting seeds: ``reset(seed=S + i)`` for i < N, S = 70000 by default, a
range nothing in the project was tuned on (the probes were tuned on 5000-5191, the env
estimates are held back on 90000-90063, the agents' earlier tables use 1000).  ``search``
(~20 simulated fetches a scene) is left out to keep the run to minutes.

    python benchmarks/agents_every_id.py --episodes 10 --seed 70000 --workers 2 \\
        --out docs/data/readme_agents.json
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import fetch_env
from benchmarks.readme_meta import meta, write_json

AGENTS = ("random", "study", "model-based")
KEEP = ("episodes", "reward_mean", "reward_ci95", "fetch_rate_mean", "fetch_rate_ci95",
        "success_rate", "success_rate_ci95", "max_log_strain_mean", "max_log_strain_max",
        "diverged")


def evaluate(env_id: str, episodes: int, seed: int, workers: int) -> dict:
    """One ``food-fetch evaluate`` run's summary, and the command that made it."""
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "eval.json"
        cmd = ["food-fetch", "evaluate", "--env", env_id, "--episodes", str(episodes),
               "--seed", str(seed), "--workers", str(workers), "--quiet", "--json", str(out)]
        cmd += [a for agent in AGENTS for a in ("--agent", agent)]
        subprocess.run(cmd, check=True)
        data = json.loads(out.read_text())
    shown = [c for c in cmd if c != str(out)]
    shown[shown.index("--json")] = "--json FILE"
    return {"command": " ".join(shown), "wall_s": data["wall_time_s"],
            "agents": {name: {k: s[k] for k in KEEP} for name, s in data["agents"].items()}}


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--episodes", type=int, default=10)
    p.add_argument("--seed", type=int, default=70000)
    p.add_argument("--workers", type=int, default=2)
    p.add_argument("--ids", nargs="+", default=list(fetch_env.ENV_IDS))
    p.add_argument("--out", type=Path, default=Path("docs/data/readme_agents.json"))
    args = p.parse_args()
    info = meta()
    start = time.perf_counter()
    results = {}
    for env_id in args.ids:
        results[env_id] = evaluate(env_id, args.episodes, args.seed, args.workers)
        print(f"{env_id}: {results[env_id]['wall_s']:.0f} s", flush=True)
    info["wall_s"] = round(time.perf_counter() - start, 1)
    write_json(args.out, {"meta": info, "episodes": args.episodes, "seed": args.seed,
                          "seeds": f"{args.seed}-{args.seed + args.episodes - 1}",
                          "results": results})
    print(f"wrote {args.out} in {info['wall_s']:.0f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
