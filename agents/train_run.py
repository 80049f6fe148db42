"""The run phase of :func:`agents.train.train`, once the request is checked and the env and
model are built, under the log directory's lock: the earlier run's files removed when
overwriting, the monitor, progress and TensorBoard logs opened (continued when resuming),
config.yml written, the callbacks (progress bar, checkpoints, evaluations, the stop on a
signal), ``learn``, and the final saves: model.zip, config.yml and, when the run ends short of
its budget, a checkpoint to resume from.

SB3 is imported only inside the functions (the ``train`` extra).
"""

from __future__ import annotations

import enum
import os
import platform
import sys
import time
from pathlib import Path
from typing import Any

import yaml

from agents.atomic import write_atomic
from agents.train import INFO_KEYS, TrainError, TrainStopped, _Plan
from agents.train_safety import (
    StopSignals,
    checkpoint_callback,
    eval_callback,
    remove_earlier_run,
    save_checkpoint,
    save_model_atomic,
    stoppable,
)


def _csv_appender(path: Path) -> Any:
    """SB3's progress.csv writer, continuing the file instead of truncating it."""
    from stable_baselines3.common.logger import CSVOutputFormat

    class AppendCSV(CSVOutputFormat):
        def __init__(self, filename: str) -> None:  # no super(): it opens with "w+"
            # r+: SB3 rewrites the header in place when a column appears, which only ever
            # lengthens the file; the earlier columns are its keys from the start.
            self.file = open(filename, "r+")  # closed by the logger
            self.keys = [k for k in self.file.readline().rstrip("\n").split(",") if k]
            self.file.seek(0, os.SEEK_END)
            self.separator = ","
            self.quotechar = '"'

    return AppendCSV(str(path))


def _open_logs(plan: _Plan, env: Any, verbose: int) -> Any:
    """Create the log dir, give the monitors their files, and return SB3's logger."""
    from stable_baselines3.common.logger import Logger, make_output_format
    from stable_baselines3.common.monitor import ResultsWriter

    (plan.log_dir / "monitor").mkdir(parents=True, exist_ok=True)
    for i, monitor in enumerate(env.envs):  # make_vec_env's Monitor, built without a file
        start = plan.monitor_starts.get(i)
        if start is not None:
            monitor.t_start = start  # times of appended episodes count from the first run
        monitor.results_writer = ResultsWriter(
            str(plan.log_dir / "monitor" / str(i)),
            header={"t_start": monitor.t_start, "env_id": plan.env_id},
            extra_keys=INFO_KEYS, override_existing=start is None)
    csv_path = plan.log_dir / "progress.csv"
    formats = [_csv_appender(csv_path) if plan.append_progress
               else make_output_format("csv", str(plan.log_dir))]
    try:
        import tensorboard  # noqa: F401

        formats.append(make_output_format("tensorboard", str(plan.log_dir)))
    except ImportError:
        pass
    if verbose:
        formats.append(make_output_format("stdout", str(plan.log_dir)))
    return Logger(folder=str(plan.log_dir), output_formats=formats)


def _plain(value: Any) -> Any:
    """A loaded model's attribute as YAML: schedules as their starting value, enums by value."""
    if value is None or isinstance(value, (bool, int, float, str)):
        return value
    if isinstance(value, enum.Enum):
        return _plain(value.value)
    if isinstance(value, dict):
        return {str(k): _plain(v) for k, v in value.items()}
    if hasattr(value, "frequency") and hasattr(value, "unit"):  # SAC's TrainFreq, as in YAML
        unit = _plain(value.unit)
        return value.frequency if unit == "step" else [value.frequency, unit]
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if callable(value):  # SB3 schedules of a float (clip_range): constant in this project
        try:
            return float(value(1.0))
        except (TypeError, ValueError):
            pass
    return str(value)


def _write_config(path: Path, config: dict[str, Any]) -> None:
    write_atomic(path, yaml.safe_dump(config, sort_keys=False))


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


def _eval_callback(plan: _Plan, eval_env: Any) -> Any:
    cb = eval_callback(eval_env, plan.log_dir / "eval", n_eval_episodes=plan.n_eval_episodes,
                       eval_freq=max(1, plan.eval_freq // plan.n_envs), deterministic=True,
                       verbose=0)
    hist = plan.eval_history
    if hist:  # continue the earlier evaluations; a new best must beat the earlier best
        cb.evaluations_timesteps = list(hist["timesteps"])
        cb.evaluations_results = list(hist["results"])
        cb.evaluations_length = list(hist["ep_lengths"])
        cb.evaluations_successes = list(hist.get("successes", []))
        if cb.evaluations_results:
            cb.best_mean_reward = max(sum(r) / len(r) for r in cb.evaluations_results)
    return cb


def _config(plan: _Plan, model: Any, eval_enabled: bool, threads: int,
            command: list[str] | None) -> dict[str, Any]:
    """config.yml: everything needed to repeat the run."""
    if plan.resume is None:
        hyperparams = {**plan.ctor, **plan.run}
    else:  # what the loaded model uses: the checkpoint's arguments and the overrides applied
        hyperparams = {**{k: _plain(getattr(model, k)) for k in plan.ctor if hasattr(model, k)},
                       **plan.run}
    resumed = plan.resume is not None
    config = {"algo": plan.algo, "env": plan.env_id, "seed": plan.seed,
              "timesteps": plan.total, "hyperparams": hyperparams,
              "run_settings": {**plan.settings, "eval": bool(eval_enabled)},
              "resumed_from": str(plan.resume) if resumed else None,
              "resumed_at_step": plan.done if resumed else None,
              "replay_buffer_from": str(plan.replay_buffer) if plan.replay_buffer else None,
              "threads": threads, "versions": _versions(),
              "command": command if command is not None else sys.argv,
              "started": time.strftime("%Y-%m-%d %H:%M:%S")}
    if plan.previous_runs:
        config["previous_runs"] = plan.previous_runs
    return config


def _callbacks(plan: _Plan, eval_env: Any, progress: bool, stop: StopSignals) -> Any:
    callbacks: list[Any] = [_progress_callback(plan.total, progress)]
    if plan.save_freq > 0:
        callbacks.append(checkpoint_callback(max(1, plan.save_freq // plan.n_envs),
                                             plan.log_dir / "checkpoints"))
    if eval_env is not None:
        callbacks.append(_eval_callback(plan, eval_env))
    return stoppable(callbacks, stop)


def _finish(plan: _Plan, model: Any, config: dict[str, Any], stop: StopSignals,
            wall: float) -> Path | None:
    """Save model.zip and the final config; a run that ended short of its budget (a stop
    signal, an error) also saves a checkpoint to resume from, whose path is returned."""
    steps = int(model.num_timesteps)
    checkpoint = None
    if steps < plan.total:
        checkpoint = save_checkpoint(model, plan.log_dir / "checkpoints")
        config["stopped"] = {"by": stop.name or "an error", "at_step": steps,
                             "checkpoint": str(checkpoint)}
    save_model_atomic(model, plan.log_dir / "model.zip")
    config.update(finished_steps=steps, wall_time_s=round(time.perf_counter() - wall, 1),
                  finished=time.strftime("%Y-%m-%d %H:%M:%S"))
    _write_config(plan.log_dir / "config.yml", config)
    return checkpoint


def _close(*envs: Any) -> None:
    for e in envs:
        if e is not None:
            e.close()


def run(plan: _Plan, env: Any, model: Any, eval_env: Any, *, progress: bool, threads: int,
        verbose: int, eval_enabled: bool, command: list[str] | None) -> Path:
    """Train under the lock: logs opened (an earlier run's files first removed when
    overwriting), config written, learn, then :func:`_finish`; TrainStopped on a signal.
    From the first file written to the last, a stop signal waits for the files to be saved
    (one that arrives before training starts skips it)."""
    stop = StopSignals()
    with stop:
        try:
            if plan.overwrite:
                remove_earlier_run(plan.log_dir)
            logger = _open_logs(plan, env, verbose)
        except OSError as exc:
            _close(env, eval_env)
            raise TrainError(f"cannot write to --log-dir {str(plan.log_dir)!r}: "
                             f"{exc.strerror}") from None
        model.set_logger(logger)
        config = _config(plan, model, eval_enabled, threads, command)
        wall = time.perf_counter()
        try:
            _write_config(plan.log_dir / "config.yml", config)
            try:
                if stop.signum is None:
                    model.learn(total_timesteps=plan.total - plan.done,
                                callback=_callbacks(plan, eval_env, progress, stop),
                                reset_num_timesteps=plan.resume is None, progress_bar=False)
            finally:
                checkpoint = _finish(plan, model, config, stop, wall)
        finally:
            logger.close()
            _close(env, eval_env)
    if stop.signum is not None and checkpoint is not None:
        raise TrainStopped(stop.name, stop.signum, int(model.num_timesteps), plan.total,
                           checkpoint, plan.log_dir)
    return plan.log_dir / "model.zip"
