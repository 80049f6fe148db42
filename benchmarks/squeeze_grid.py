"""Reward of every squeeze on a grid, scene by scene, on an id's tuning scenes.

Run: python benchmarks/squeeze_grid.py --env FoodFetch-Diced-v1 [--seeds 100:300] \\
         [--squeezes 0,0.02,...] [--speeds 0.4:0.04,0.2:0.02] [--max-young MPA] \\
         [--workers 2] [--out JSON]

On each scene ``reset(seed=s)`` of the tuning seeds (default 100-299, never the reporting
seeds from 80000) every nominal squeeze of the span (``eps``: each face presses
``eps * span_along / 2`` into the plate, the model-based agent's ``clamp_angle``) is fetched
at every (clamp speed, lift speed) pair with ``env.unwrapped.simulate_action``, and so is
the shipped model-based agent's own action.  The physics is deterministic, so a scene's row
is the reward any policy that picks one of these actions would get there.  ``--max-young``
keeps only the scenes whose stiffest piece is at most that modulus (the scene reset builds,
without the probes), to study one stiffness level of a plate family.  Writes the
scenes as they finish to ``JSON.jsonl`` (a stopped run keeps them; a rerun skips them), then
``JSON``: the scenes and, per action, the mean reward with its 95 % interval, the spread,
the paired difference to the best squeeze at each speed, and the plates with a reward below
-0.3 (a badly crushed plate); also the shipped model-based agent's and, as ``grip_rule``,
the same agent made to size every squeeze by its grip rule (``ModelBasedConfig(layout=
"block")``: the squeeze from the probed piece, the clamp slowed before the probed piece
would stall the motor).  How ``eps_diced`` was chosen (``agents.model_based``).
"""

from __future__ import annotations

import argparse
import json
import sys
import warnings
from concurrent.futures import ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

import fetch_env  # noqa: F401  (registers the ids)
from agents.evaluate import _close_pool, mean_ci
from agents.model_based import ModelBasedAgent, ModelBasedConfig, clamp_angle
from fetch_env.env import ACTION_RANGES, decode_observation, physical_to_action
from fetch_env.scene import Geometry

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from benchmarks.readme_meta import meta, write_json  # noqa: E402
from benchmarks.theta_sweep import seed_range  # noqa: E402
from fetch_env.parallel import stop_exit_code, stop_on_signals, worker_signals  # noqa: E402

SQUEEZES = (0.0, 0.02, 0.04, 0.06, 0.08, 0.10, 0.12, 0.15, 0.18, 0.22, 0.27)
SPEEDS = ((0.4, 0.04), (0.2, 0.02))  # (omega [rad/s], lift_speed [m/s])
CRUSHED = -0.3  # a reward below this is a plate with a badly crushed die


def scene_row(env_id: str, seed: int, squeezes: tuple[float, ...],
              speeds: tuple[tuple[float, float], ...]) -> dict[str, Any]:
    """Every (squeeze, speeds) action and the model-based agent's on one scene."""
    warnings.filterwarnings("ignore")
    env = gym.make(env_id)
    obs, _ = env.reset(seed=seed)
    sim = env.unwrapped
    d = {k: float(v) for k, v in decode_observation(obs).items()}
    width = d["span_along"] if d["span_along"] > 0 else d["mean_size"]
    lo, hi = ACTION_RANGES["theta_d"]
    grid = []
    for eps in squeezes:
        theta = float(np.clip(clamp_angle(Geometry(), d["max_height"], eps * width / 2), lo, hi))
        for omega, lift in speeds:
            reward, info = sim.simulate_action(physical_to_action(theta, omega, lift))
            grid.append({"eps": eps, "theta_d": theta, "omega": omega, "lift_speed": lift,
                         "reward": float(reward), "fetch_rate": float(info["fetch_rate"]),
                         "max_log_strain": float(info["max_log_strain"])})
    agents = {}
    for name, config in (("model_based", None), ("grip_rule", ModelBasedConfig(layout="block"))):
        agent = ModelBasedAgent(config)
        agent.begin_episode(env)
        reward, _ = sim.simulate_action(agent.act(obs))
        agents[name] = {"reward": float(reward), "theta_d": agent.last_plan["theta_d"],
                        "omega": agent.last_plan["omega"]}
    env.close()
    return {"seed": seed, "obs": d, "grid": grid, **agents}


def stiffest_young(env_id: str, seed: int) -> float:
    """[Pa] the stiffest piece of the scene ``reset(seed=seed)`` builds, without the probes
    (``estimator="none"``) or a fetch."""
    return stiffest_youngs(env_id, [seed])[seed]


def stiffest_youngs(env_id: str, seeds: list[int]) -> dict[int, float]:
    """:func:`stiffest_young` of each of ``seeds``, on one env."""
    env = gym.make(env_id, estimator="none")
    out = {}
    for seed in seeds:
        env.reset(seed=seed)
        out[seed] = max(p.material.young for p in env.unwrapped.pieces)
    env.close()
    return out


def _ci(x: np.ndarray) -> list[float]:
    """The Student-t 95 % interval of the mean, as ``food-fetch evaluate`` reports it."""
    _, lo, hi = mean_ci(x)
    return [lo, hi]


def summarize(rows: list[dict[str, Any]]) -> dict[str, Any]:
    """Per action: mean reward [95 %], spread, crushed plates, paired gap to the speed's best."""
    rewards = np.array([[g["reward"] for g in r["grid"]] for r in rows])
    cells = [(g["eps"], g["omega"], g["lift_speed"]) for g in rows[0]["grid"]]
    actions = []
    for speed in sorted({c[1:] for c in cells}, reverse=True):
        cols = [j for j, c in enumerate(cells) if c[1:] == speed]
        best = max(cols, key=lambda j: rewards[:, j].mean())
        for j in cols:
            x, gap = rewards[:, j], rewards[:, j] - rewards[:, best]
            actions.append({"eps": cells[j][0], "omega": speed[0], "lift_speed": speed[1],
                            "reward_mean": float(x.mean()), "reward_ci95": _ci(x),
                            "reward_sd": float(x.std(ddof=1)),
                            "crushed_plates": int((x < CRUSHED).sum()),
                            "minus_best": {"mean": float(gap.mean()),
                                           "ci95": _ci(gap) if j != best else [0.0, 0.0]}})
    agents = {}
    for name in ("model_based", "grip_rule"):
        x = np.array([r[name]["reward"] for r in rows])
        agents[name] = {"reward_mean": float(x.mean()), "reward_ci95": _ci(x),
                        "reward_sd": float(x.std(ddof=1)),
                        "crushed_plates": int((x < CRUSHED).sum())}
    gain = np.array([r["model_based"]["reward"] - r["grip_rule"]["reward"] for r in rows])
    agents["model_based_minus_grip_rule"] = {"mean": float(gain.mean()), "ci95": _ci(gain)}
    return {"n_scenes": len(rows), "actions": actions, **agents,
            "best_of_grid": {"reward_mean": float(rewards.max(1).mean()),
                             "reward_ci95": _ci(rewards.max(1))}}


def least_squeeze_near_best(summary: dict[str, Any], omega: float) -> float:
    """The least squeeze at clamp speed ``omega`` whose paired 95 % interval against the
    best squeeze there includes 0 (the best's spread of outcomes is a lottery's, so a
    squeeze not clearly worse and with fewer crushed plates is the safer choice)."""
    ok = [a["eps"] for a in summary["actions"]
          if a["omega"] == omega and a["minus_best"]["ci95"][1] >= 0.0]
    return min(ok)


def _floats(text: str) -> tuple[float, ...]:
    try:
        return tuple(float(v) for v in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"expected comma-separated numbers, got {text!r}") from None


def _speeds(text: str) -> tuple[tuple[float, float], ...]:
    try:
        pairs = tuple(tuple(float(v) for v in item.split(":")) for item in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected OMEGA:LIFT pairs, got {text!r}") from None
    if any(len(p) != 2 for p in pairs):
        raise argparse.ArgumentTypeError(f"expected OMEGA:LIFT pairs, got {text!r}")
    return pairs  # type: ignore[return-value]


def _run_scenes(args: argparse.Namespace, todo: list[int], stream: Path,
                done: dict[int, dict[str, Any]]) -> None:
    """Run the ``todo`` scenes on ``args.workers`` processes, appending each to ``stream``
    (and ``done``) as it finishes; after a stop or a lost worker the workers end too."""
    pool = ProcessPoolExecutor(args.workers, initializer=worker_signals)
    clean = False
    try:
        with stream.open("a") as f:
            jobs = [pool.submit(scene_row, args.env, s, args.squeezes, args.speeds) for s in todo]
            for job in jobs:
                row = job.result()
                done[row["seed"]] = row
                f.write(json.dumps(row) + "\n")
                f.flush()
        clean = True
    finally:
        _close_pool(pool, clean)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--env", required=True)
    p.add_argument("--seeds", type=seed_range, default=range(100, 300), help="LO:HI")
    p.add_argument("--squeezes", type=_floats, default=SQUEEZES)
    p.add_argument("--speeds", type=_speeds, default=SPEEDS, help="OMEGA:LIFT,...")
    p.add_argument("--max-young", type=float, default=None, metavar="MPA",
                   help="only the scenes whose stiffest piece is at most this modulus")
    p.add_argument("--workers", type=int, default=1)
    p.add_argument("--out", type=Path, default=None)
    args = p.parse_args(argv)
    if args.env not in gym.registry:
        p.error(f"unknown env id {args.env!r}")
    if args.workers < 1:
        p.error(f"--workers must be >= 1, got {args.workers}")
    if args.max_young is not None and not args.max_young > 0:
        p.error(f"--max-young must be > 0 MPa, got {args.max_young}")
    seeds = list(args.seeds)
    if args.max_young is not None:
        young = stiffest_youngs(args.env, seeds)
        seeds = [s for s in seeds if young[s] <= args.max_young * 1e6]
        if not seeds:
            p.error(f"no scene of seeds {args.seeds.start}-{args.seeds.stop - 1} has its "
                    f"stiffest piece at most {args.max_young} MPa")
    out = args.out or ROOT / "docs" / "data" / "tuning" / f"{args.env}_squeeze_grid.json"
    stream = out.with_suffix(".jsonl")
    done: dict[int, dict[str, Any]] = {}
    if stream.exists():
        for line in stream.read_text().splitlines():
            row = json.loads(line)
            done[row["seed"]] = row
    todo = [s for s in seeds if s not in done]
    out.parent.mkdir(parents=True, exist_ok=True)
    stop_on_signals()
    try:
        _run_scenes(args, todo, stream, done)
    except (KeyboardInterrupt, BrokenProcessPool) as exc:
        why = "stopped" if isinstance(exc, KeyboardInterrupt) else "a worker process died"
        print(f"{why}; the {len(done)} finished scenes are in {stream}; rerun the same "
              "command to continue", file=sys.stderr)
        return stop_exit_code(exc) if isinstance(exc, KeyboardInterrupt) else 1
    rows = [done[s] for s in seeds]
    summary = summarize(rows)
    fast = max(o for o, _ in args.speeds)
    summary["least_squeeze_near_best"] = {"omega": fast,
                                          "eps": least_squeeze_near_best(summary, fast)}
    write_json(out, {"env_id": args.env, "seeds": f"{args.seeds.start}-{args.seeds.stop - 1}",
                     "max_young_mpa": args.max_young, "meta": meta(), "summary": summary,
                     "scenes": rows})
    mb, grip = summary["model_based"], summary["grip_rule"]
    eps = summary["least_squeeze_near_best"]["eps"]
    print(f"{args.env}, {len(rows)} scenes: model-based {mb['reward_mean']:+.3f}, grip rule "
          f"{grip['reward_mean']:+.3f}; least squeeze within the best's interval at {fast} "
          f"rad/s: {eps}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
