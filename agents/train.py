"""Train PPO or SAC on a ``FoodFetch-*`` environment with Stable-Baselines3.

Hyperparameters live in ``agents/hyperparams/<algo>.yml``, one key per environment id (the
rl-baselines3-zoo convention), and can be overridden per run.  A run writes, under its log
directory::

    model.zip              the final policy (``food-fetch evaluate --agent DIR/model.zip``)
    config.yml             everything needed to repeat the run (algo, env, seed, budget,
                           hyperparameters, versions, command line)
    progress.csv           SB3's logger (plus TensorBoard event files if tensorboard is installed)
    monitor/               per-episode reward, fetch rate, LE, success (SB3 Monitor CSVs)
    eval/                  EvalCallback: evaluations.npz and best_model.zip
    checkpoints/           CheckpointCallback: rl_model_<steps>_steps.zip (+ SAC replay buffer)

SB3 and torch are imported only inside the functions (they are the ``train`` extra).
"""

from __future__ import annotations

import copy
import platform
import sys
import time
from importlib import resources
from pathlib import Path
from typing import Any

import yaml

ALGOS: tuple[str, ...] = ("ppo", "sac")
# Keys of the YAML files that are not arguments of the SB3 constructor.
RUN_KEYS: tuple[str, ...] = ("n_envs", "n_timesteps", "policy", "eval_freq", "n_eval_episodes",
                             "checkpoint_freq", "env_kwargs")
EVAL_SEED_OFFSET = 1_000_003  # eval scenes never coincide with training scenes


class TrainError(Exception):
    """A bad training request (unknown id, missing file, bad hyperparameter): one line."""


def env_ids() -> tuple[str, ...]:
    """The ``FoodFetch-*`` ids (``fetch_env.ENV_IDS``, which importing ``fetch_env``
    registers), sorted."""
    from fetch_env import ENV_IDS

    return tuple(sorted(ENV_IDS))


def hyperparams_path(algo: str) -> Path:
    return Path(str(resources.files("agents") / "hyperparams" / f"{algo}.yml"))


def load_hyperparams(algo: str, env_id: str, file: str | Path | None = None,
                     overrides: dict[str, Any] | None = None) -> dict[str, Any]:
    """The hyperparameters for ``env_id`` from the shipped YAML (or ``file``), overridden."""
    if algo not in ALGOS:
        raise TrainError(f"unknown algorithm {algo!r}; choose from {', '.join(ALGOS)}")
    path = Path(file) if file is not None else hyperparams_path(algo)
    try:
        table = yaml.safe_load(path.read_text())
    except OSError as exc:
        raise TrainError(f"cannot read hyperparameter file {str(path)!r}: {exc.strerror}") from None
    except yaml.YAMLError as exc:
        raise TrainError(f"hyperparameter file {str(path)!r} is not valid YAML: "
                         f"{str(exc).splitlines()[0]}") from None
    if not isinstance(table, dict) or env_id not in table:
        known = ", ".join(table) if isinstance(table, dict) else "none"
        raise TrainError(f"no {algo} hyperparameters for {env_id!r} in {str(path)!r} "
                         f"(ids there: {known})")
    hp = copy.deepcopy(table[env_id])
    hp.update(copy.deepcopy(overrides or {}))
    return hp


def parse_override(text: str) -> tuple[str, Any]:
    """``key=value`` with the value read as YAML (``learning_rate=1e-3``, ``net_arch=[32]``)."""
    if "=" not in text:
        raise TrainError(f"hyperparameter override must be key=value, got {text!r}")
    key, value = text.split("=", 1)
    try:
        return key.strip(), yaml.safe_load(value)
    except yaml.YAMLError:
        raise TrainError(f"cannot read the value of override {text!r}") from None


def _versions() -> dict[str, str]:
    import gymnasium
    import mujoco
    import numpy
    import stable_baselines3
    import torch

    return {"python": platform.python_version(),
            "stable_baselines3": str(stable_baselines3.__version__),
            "torch": str(torch.__version__), "gymnasium": str(gymnasium.__version__),
            "mujoco": str(mujoco.__version__), "numpy": str(numpy.__version__),
            "machine": f"{platform.machine()} {platform.system()}"}


def _progress_callback(total: int, enabled: bool) -> Any:
    """A tqdm progress bar (SB3's own needs ``rich`` as well)."""
    from stable_baselines3.common.callbacks import BaseCallback

    class TqdmCallback(BaseCallback):
        def _on_training_start(self) -> None:
            from tqdm import tqdm

            self.pbar = tqdm(total=total, initial=min(self.model.num_timesteps, total),
                             unit="step", disable=not enabled, dynamic_ncols=True)

        def _on_step(self) -> bool:
            self.pbar.update(self.training_env.num_envs)
            return True

        def _on_training_end(self) -> None:
            self.pbar.close()

    return TqdmCallback()


def _find_replay_buffer(checkpoint: Path) -> Path | None:
    # CheckpointCallback: rl_model_<n>_steps.zip next to rl_model_replay_buffer_<n>_steps.pkl
    stem = checkpoint.stem
    if stem.endswith("_steps") and "_" in stem[:-6]:
        prefix, n = stem[:-6].rsplit("_", 1)
        cand = checkpoint.with_name(f"{prefix}_replay_buffer_{n}_steps.pkl")
        if cand.exists():
            return cand
    return None


def train(algo: str, env_id: str, timesteps: int | None, seed: int, log_dir: str | Path, *,
          resume: str | Path | None = None, hyperparams_file: str | Path | None = None,
          overrides: dict[str, Any] | None = None, progress: bool = True,
          threads: int = 1, verbose: int = 0, eval_enabled: bool = True,
          command: list[str] | None = None) -> Path:
    """Train and save ``log_dir/model.zip``; returns its path.

    ``timesteps`` is the total budget (the YAML's ``n_timesteps`` when None); resuming from
    ``resume`` (a checkpoint .zip) continues the step count up to that total.
    """
    ids = env_ids()
    if env_id not in ids:
        raise TrainError(f"unknown environment id {env_id!r}; choose from {', '.join(ids)}")
    hp = load_hyperparams(algo, env_id, hyperparams_file, overrides)
    total = int(timesteps if timesteps is not None else hp.get("n_timesteps", 10_000))
    if total < 1:
        raise TrainError(f"--timesteps must be >= 1, got {total}")
    if resume is not None and not Path(resume).is_file():
        raise TrainError(f"checkpoint not found: {str(resume)!r}")
    log_dir = Path(log_dir)
    log_dir.mkdir(parents=True, exist_ok=True)

    import torch
    from stable_baselines3 import PPO, SAC
    from stable_baselines3.common.callbacks import CallbackList, CheckpointCallback, EvalCallback
    from stable_baselines3.common.env_util import make_vec_env
    from stable_baselines3.common.logger import configure
    from stable_baselines3.common.utils import set_random_seed

    torch.set_num_threads(max(1, int(threads)))
    set_random_seed(seed)
    cls = {"ppo": PPO, "sac": SAC}[algo]
    run = {k: hp.pop(k) for k in RUN_KEYS if k in hp}
    n_envs = int(run.get("n_envs", 1))
    # make_vec_env asks for rgb_array frames by default: no rendering while training.
    env_kwargs = {"render_mode": None, **dict(run.get("env_kwargs") or {})}
    info_keys = ("fetch_rate", "max_log_strain", "is_success")
    (log_dir / "monitor").mkdir(exist_ok=True)
    env = make_vec_env(env_id, n_envs=n_envs, seed=seed, env_kwargs=env_kwargs,
                       monitor_dir=str(log_dir / "monitor"),
                       monitor_kwargs={"info_keywords": info_keys})
    formats = ["csv"]
    try:
        import tensorboard  # noqa: F401

        formats.append("tensorboard")
    except ImportError:
        pass
    if verbose:
        formats.append("stdout")
    logger = configure(str(log_dir), formats)

    try:
        if resume is not None:
            model = cls.load(str(resume), env=env, device="cpu")
            buf = _find_replay_buffer(Path(resume)) if algo == "sac" else None
            if buf is not None:
                model.load_replay_buffer(str(buf))
        else:
            model = cls(run.get("policy", "MlpPolicy"), env, seed=seed, device="cpu",
                        verbose=verbose, **hp)
    except (TypeError, ValueError) as exc:
        env.close()
        raise TrainError(f"bad {algo} hyperparameters for {env_id}: {exc}") from None
    model.set_logger(logger)
    done = int(model.num_timesteps) if resume is not None else 0

    config = {"algo": algo, "env": env_id, "seed": seed, "timesteps": total,
              "hyperparams": {**hp, **run}, "resumed_from": str(resume) if resume else None,
              "resumed_at_step": done if resume else None, "threads": threads,
              "versions": _versions(),
              "command": command if command is not None else sys.argv,
              "started": time.strftime("%Y-%m-%d %H:%M:%S")}
    (log_dir / "config.yml").write_text(yaml.safe_dump(config, sort_keys=False))

    callbacks: list[Any] = [_progress_callback(total, progress)]
    ckpt_freq = int(run.get("checkpoint_freq", 0))
    if ckpt_freq > 0:
        callbacks.append(CheckpointCallback(
            save_freq=max(1, ckpt_freq // n_envs), save_path=str(log_dir / "checkpoints"),
            save_replay_buffer=algo == "sac"))
    eval_env = None
    eval_freq = int(run.get("eval_freq", 0))
    if eval_enabled and eval_freq > 0:
        eval_env = make_vec_env(env_id, n_envs=1, seed=seed + EVAL_SEED_OFFSET,
                                env_kwargs=env_kwargs)
        callbacks.append(EvalCallback(
            eval_env, n_eval_episodes=int(run.get("n_eval_episodes", 10)),
            eval_freq=max(1, eval_freq // n_envs), log_path=str(log_dir / "eval"),
            best_model_save_path=str(log_dir / "eval"), deterministic=True, verbose=0))
    wall = time.perf_counter()
    try:
        model.learn(total_timesteps=max(total - done, 0), callback=CallbackList(callbacks),
                    reset_num_timesteps=resume is None, progress_bar=False)
    finally:
        out = log_dir / "model.zip"
        model.save(str(out))
        config.update(finished_steps=int(model.num_timesteps),
                      wall_time_s=round(time.perf_counter() - wall, 1),
                      finished=time.strftime("%Y-%m-%d %H:%M:%S"))
        (log_dir / "config.yml").write_text(yaml.safe_dump(config, sort_keys=False))
        env.close()
        if eval_env is not None:
            eval_env.close()
    return out
