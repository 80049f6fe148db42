"""Training with RLlib, Ray's RL library (``food-fetch train --backend rllib``).

RLlib collects experience with N env runners (Ray actors, each stepping its own
environment) and learns in the driver, on a local Ray instance or an existing cluster, which
is what a lab with a cluster needs and Stable-Baselines3 (one process) cannot give.  The run
keeps the SB3 backend's promises: one run per ``--log-dir`` (a lock naming the holder), an
earlier run replaced only with ``--overwrite``, RLlib checkpoints every ``save_freq``
iterations and at the end, SIGTERM/SIGHUP/Ctrl-C ending the run after the current iteration
with a checkpoint, ``progress.csv`` streamed per iteration and ``config.yml`` to repeat it.
The trained actor is exported to ``policy.npz`` (:mod:`agents.rllib_policy`), which
``food-fetch evaluate --agent`` runs without Ray, torch or pickle.

Hyperparameters: ``agents/hyperparams/rllib_<algo>.yml``, one block per environment id.
"""

from __future__ import annotations

import csv
import shutil
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from agents.train import TrainError

HYPERPARAMS_DIR = Path(__file__).parent / "hyperparams"
RUN_NAMES = ("policy.npz", "policy.json", "config.yml", "progress.csv", "checkpoints")


class RLlibStopped(KeyboardInterrupt):
    """Training ended early on a stop signal, after saving ``checkpoint`` and the policy."""

    def __init__(self, signame: str, signum: int, steps: int, total: int,
                 checkpoint: Path) -> None:
        self.signame, self.signum, self.steps, self.total = signame, signum, steps, total
        self.checkpoint = checkpoint
        super().__init__(self.one_line())

    def one_line(self) -> str:
        return (f"stopped by {self.signame} at step {self.steps} of {self.total}; saved the "
                f"RLlib checkpoint {self.checkpoint} and the policy so far beside it")


@dataclass
class RLlibPlan:
    algo: str
    env_id: str
    timesteps: int
    seed: int
    log_dir: Path
    env_runners: int
    address: str
    save_freq: int  # fetches between checkpoints (<= 0: only at the end)
    settings: dict[str, Any]
    env_kwargs: dict[str, Any] = field(default_factory=dict)  # the env's (e.g. quasi-static)


def load_settings(algo: str, env_id: str, path: Path | None = None) -> dict[str, Any]:
    """The block of ``env_id`` in ``rllib_<algo>.yml`` (or ``path``)."""
    import yaml

    path = path or HYPERPARAMS_DIR / f"rllib_{algo}.yml"
    try:
        table = yaml.safe_load(path.read_text())
    except (OSError, yaml.YAMLError) as exc:
        raise TrainError(f"cannot read {str(path)!r}: {exc}") from None
    if not isinstance(table, dict) or env_id not in table:
        raise TrainError(f"{str(path)!r} has no block for {env_id}")
    block = table[env_id]
    unknown = set(block) - {"n_timesteps", "training", "model", "env_runners", "reporting"}
    if unknown:
        raise TrainError(f"{str(path)!r}: unknown key(s) {', '.join(sorted(unknown))} in the "
                         f"block of {env_id}")
    return block


def check_log_dir(log_dir: Path, overwrite: bool) -> None:
    """Refuse a folder that holds an earlier run (of either backend) unless ``overwrite``."""
    from agents.train_safety import check_unlocked, earlier_run

    check_unlocked(log_dir)
    held = earlier_run(log_dir) or next((n for n in RUN_NAMES if (log_dir / n).exists()),
                                        None)
    if held is not None and not overwrite:
        raise TrainError(f"--log-dir {str(log_dir)!r} holds an earlier run ({held}); give "
                         "--overwrite to replace it, or another --log-dir")


def _make_env(config: dict[str, Any]) -> Any:
    import gymnasium as gym

    import fetch_env  # noqa: F401  (registers the ids in the env runner's process)

    return gym.make(config["env_id"], **config.get("env_kwargs", {}))


def build_config(plan: RLlibPlan) -> Any:
    """The RLlib AlgorithmConfig of the plan (the env registered under ``food-fetch``)."""
    from ray.rllib.core.rl_module.default_model_config import DefaultModelConfig
    from ray.tune.registry import register_env

    register_env("food-fetch", _make_env)
    if plan.algo == "ppo":
        from ray.rllib.algorithms.ppo import PPOConfig as Config
    else:
        from ray.rllib.algorithms.sac import SACConfig as Config
    s = plan.settings
    try:
        config = (Config().environment("food-fetch", env_config={
                      "env_id": plan.env_id, "env_kwargs": dict(plan.env_kwargs)})
                  .env_runners(num_env_runners=plan.env_runners, **s.get("env_runners", {}))
                  .training(**s.get("training", {}))
                  .rl_module(model_config=DefaultModelConfig(**s.get("model", {})))
                  .reporting(**s.get("reporting", {}))
                  .debugging(seed=plan.seed))
        config.validate()
    except (TypeError, ValueError) as exc:
        raise TrainError(f"RLlib refuses the settings of {plan.env_id}: "
                         f"{str(exc).splitlines()[0]}") from None
    return config


def _checkpoint(algo: Any, log_dir: Path, steps: int) -> Path:
    """An RLlib checkpoint under ``checkpoints/``, written to a temporary folder and moved
    into place, so a stop mid-write never leaves half a checkpoint under its final name."""
    final = log_dir / "checkpoints" / f"rllib_{steps}_steps"
    tmp = final.with_name(final.name + ".tmp")
    shutil.rmtree(tmp, ignore_errors=True)
    algo.save_to_path(str(tmp.resolve()))  # RLlib reads a relative path as a bad URI
    shutil.rmtree(final, ignore_errors=True)
    tmp.rename(final)
    return final


def _export(algo: Any, plan: RLlibPlan) -> Path:
    from agents.rllib_policy import export_policy

    rng = np.random.default_rng(plan.seed)
    module = algo.get_module()
    dim = int(np.prod(module.observation_space.shape))
    check = rng.uniform(-3.0, 3.0, (16, dim)).astype(np.float32)
    return export_policy(module, plan.algo, plan.env_id, plan.log_dir, check)


def _write_config(plan: RLlibPlan, command: list[str]) -> None:
    import ray
    import torch
    import yaml

    from agents.atomic import write_atomic

    config = {"backend": "rllib", "algo": plan.algo, "env_id": plan.env_id,
              "timesteps": plan.timesteps, "seed": plan.seed, "env_runners": plan.env_runners,
              "ray_address": plan.address, "save_freq": plan.save_freq,
              "settings": plan.settings, "env_kwargs": dict(plan.env_kwargs),
              "command": command,
              "versions": {"ray": ray.__version__, "torch": str(torch.__version__),
                           "python": sys.version.split()[0]}}
    write_atomic(plan.log_dir / "config.yml", yaml.safe_dump(config, sort_keys=False))


def _steps(result: dict[str, Any]) -> int:
    value = result.get("num_env_steps_sampled_lifetime")
    if value is None:
        value = result.get("env_runners", {}).get("num_env_steps_sampled_lifetime", 0)
    return int(value)


def _train_loop(algo: Any, plan: RLlibPlan, progress: bool) -> tuple[int, Path | None, Any]:
    """Iterations until the budget or a stop; (steps, last checkpoint, the stop signals)."""
    from tqdm import tqdm

    from agents.train_safety import StopSignals

    steps, iteration, mark = 0, 0, 0
    last: Path | None = None
    last_steps = -1
    bar = tqdm(total=plan.timesteps, unit="step", disable=not progress or None,
               file=sys.stderr, desc=f"rllib {plan.algo} {plan.env_id}")
    with (plan.log_dir / "progress.csv").open("w", newline="") as f, StopSignals() as stop:
        writer = csv.writer(f)
        writer.writerow(["iteration", "steps", "episode_return_mean", "wall_s"])
        start = time.perf_counter()
        while steps < plan.timesteps and stop.signum is None:
            result = algo.train()
            iteration += 1
            bar.update(_steps(result) - steps)
            steps = _steps(result)
            ret = result.get("env_runners", {}).get("episode_return_mean", float("nan"))
            writer.writerow([iteration, steps, ret, round(time.perf_counter() - start, 2)])
            f.flush()
            if plan.save_freq > 0 and steps // plan.save_freq > mark:
                mark = steps // plan.save_freq
                last, last_steps = _checkpoint(algo, plan.log_dir, steps), steps
        bar.close()
        if last_steps != steps:  # the end (or the stop) not yet checkpointed
            last = _checkpoint(algo, plan.log_dir, steps)
        return steps, last, stop


def train_rllib(plan: RLlibPlan, *, overwrite: bool, progress: bool,
                command: list[str]) -> Path:
    """Train, checkpoint and export; the path of ``policy.npz``.  Raises
    :class:`RLlibStopped` (after saving) on a stop signal, TrainError on a bad request."""
    from agents.ray_runner import RaySetupError, connected
    from agents.train_safety import RunLock

    check_log_dir(plan.log_dir, overwrite)
    try:
        with connected(plan.address, plan.env_runners + 1):
            config = build_config(plan)
            lock = RunLock.acquire(plan.log_dir, command)
            try:
                if overwrite:
                    for name in RUN_NAMES:
                        target = plan.log_dir / name
                        if target.is_dir():
                            shutil.rmtree(target)
                        elif target.exists():
                            target.unlink()
                _write_config(plan, command)
                algo = config.build_algo()
                try:
                    steps, ckpt, stop = _train_loop(algo, plan, progress)
                    policy = _export(algo, plan)
                finally:
                    algo.stop()
            finally:
                lock.release()
    except RaySetupError as exc:
        raise TrainError(str(exc)) from None
    if stop.signum is not None:
        assert ckpt is not None
        raise RLlibStopped(stop.name, stop.signum, steps, plan.timesteps, ckpt)
    return policy
