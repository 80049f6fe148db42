"""Model-based agent settings on an id's tuning scenes: one run per value of one config field.

Run: python benchmarks/model_based_tuning.py --env FoodFetch-TwoRows-v1 \\
         --field eps_min_two_rows --values 0.05,0.06,0.07 [--seeds 100:140] [--out JSON]

Each value runs ``ModelBasedAgent(ModelBasedConfig(field=value))`` on the scenes
``reset(seed=s)`` of the tuning seeds (default 100-139, never the reporting seeds from 80000)
and records every scene's reward, clamp angle and the mean with its 95 % interval (Student t).
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import warnings
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
from scipy import stats

import fetch_env  # noqa: F401  (registers the ids)
from agents.model_based import ModelBasedAgent, ModelBasedConfig

ROOT = Path(__file__).resolve().parents[1]


def run_value(env: gym.Env, field: str, value: float, seeds: range) -> dict[str, Any]:
    """The agent with ``field=value`` on every seed's scene."""
    agent = ModelBasedAgent(ModelBasedConfig(**{field: value}))
    rewards, thetas = [], []
    for seed in seeds:
        obs, _ = env.reset(seed=seed)
        agent.begin_episode(env)
        _, reward, _, _, _ = env.step(agent.act(obs))
        rewards.append(float(reward))
        thetas.append(agent.last_plan["theta_d"])
    r = np.array(rewards)
    half = float(stats.t.ppf(0.975, r.size - 1) * r.std(ddof=1) / np.sqrt(r.size))
    return {"value": value, "reward_mean": float(r.mean()),
            "reward_ci95": [float(r.mean()) - half, float(r.mean()) + half],
            "rewards": rewards, "theta_d": thetas}


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--env", required=True)
    p.add_argument("--field", required=True, help="a ModelBasedConfig field")
    p.add_argument("--values", required=True, help="comma-separated numbers")
    p.add_argument("--seeds", default="100:140", help="LO:HI (default 100:140)")
    p.add_argument("--out", type=Path, default=None)
    args = p.parse_args(argv)
    lo, hi = (int(x) for x in args.seeds.split(":"))
    values = [float(v) for v in args.values.split(",")]
    if args.field not in ModelBasedConfig.__dataclass_fields__:
        p.error(f"unknown ModelBasedConfig field {args.field!r}")
    out = args.out or ROOT / "docs" / "data" / "tuning" / f"{args.env}_{args.field}.json"
    out.parent.mkdir(parents=True, exist_ok=True)
    warnings.filterwarnings("ignore", module="gymnasium")
    env = gym.make(args.env)
    runs = []
    for value in values:
        runs.append(run_value(env, args.field, value, range(lo, hi)))
        ci = runs[-1]["reward_ci95"]
        print(f"{args.field}={value:g}: {runs[-1]['reward_mean']:+.3f} "
              f"[{ci[0]:+.3f}, {ci[1]:+.3f}]", flush=True)
    data = {"env_id": args.env, "field": args.field, "seeds": f"{lo}-{hi - 1}",
            "command": "python benchmarks/model_based_tuning.py " + " ".join(
                sys.argv[1:] if argv is None else argv), "runs": runs}
    tmp = out.with_suffix(".json.tmp")
    tmp.write_text(json.dumps(data, indent=1) + "\n")
    os.replace(tmp, out)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
