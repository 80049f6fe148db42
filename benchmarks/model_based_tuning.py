"""Model-based agent settings on an id's tuning scenes: one run per value of one config field.

Run: python benchmarks/model_based_tuning.py --env FoodFetch-TwoRows-v1 \\
         --field eps_min_two_rows --values 0.05,0.06,0.07 [--seeds 100:140] [--out JSON]

Each value runs ``ModelBasedAgent(ModelBasedConfig(field=value))`` on the scenes
``reset(seed=s)`` of the tuning seeds (default 100-139, never the reporting seeds from 80000)
and records every scene's reward, clamp angle and the mean with its 95 % interval (Student t).
The JSON is rewritten atomically after each value, so a stopped run keeps what finished.
"""

from __future__ import annotations

import argparse
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
sys.path.insert(0, str(ROOT))

from benchmarks.readme_meta import meta, write_json  # noqa: E402
from benchmarks.theta_sweep import seed_range  # noqa: E402


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
    p.add_argument("--seeds", type=seed_range, default=range(100, 140),
                   help="LO:HI (default 100:140)")
    p.add_argument("--out", type=Path, default=None)
    args = p.parse_args(argv)
    try:
        values = [float(v) for v in args.values.split(",")]
    except ValueError:
        p.error(f"--values must be numbers, got {args.values!r}")
    if args.field not in ModelBasedConfig.__dataclass_fields__:
        p.error(f"unknown ModelBasedConfig field {args.field!r}")
    out = args.out or ROOT / "docs" / "data" / "tuning" / f"{args.env}_{args.field}.json"
    warnings.filterwarnings("ignore", module="gymnasium")
    env = gym.make(args.env)
    data: dict[str, Any] = {"env_id": args.env, "field": args.field,
                            "seeds": f"{args.seeds.start}-{args.seeds.stop - 1}",
                            "meta": meta(), "runs": [], "complete": False}
    for value in values:
        data["runs"].append(run_value(env, args.field, value, args.seeds))
        write_json(out, data)
        run = data["runs"][-1]
        print(f"{args.field}={value:g}: {run['reward_mean']:+.3f} "
              f"[{run['reward_ci95'][0]:+.3f}, {run['reward_ci95'][1]:+.3f}]", flush=True)
    data["complete"] = True
    write_json(out, data)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
