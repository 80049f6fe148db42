"""Train PPO or SAC on a ``FoodFetch-*`` environment with Stable-Baselines3.

Hyperparameters live in ``agents/hyperparams/<algo>.yml``, one key per environment id, in
rl_zoo3's format (``python -m rl_zoo3.train --conf-file`` reads the same files: SB3's
constructor arguments plus the zoo's ``n_envs``, ``n_timesteps``, ``policy``, ``env_kwargs``),
and can be overridden per run.  The run settings, how often to evaluate and to checkpoint, are
not hyperparameters: they are arguments (``--eval-freq``, ``--eval-episodes``, ``--save-freq``,
named as rl_zoo3's flags).  A run writes, under its log directory::

    model.zip              the final policy (``food-fetch evaluate --agent DIR/model.zip``)
    config.yml             everything needed to repeat the run (algo, env, seed, budget,
                           hyperparameters actually used, versions, command line)
    progress.csv           SB3's logger (plus TensorBoard event files if tensorboard is installed)
    monitor/               per-episode reward, fetch rate, LE, success (SB3 Monitor CSVs)
    eval/                  EvalCallback: evaluations.npz and best_model.zip
    checkpoints/           rl_model_<steps>_steps.zip (+ SAC's replay buffer, as
                           rl_model_replay_buffer_<steps>_steps.npz)
    train.lock             while the run lives: its process id, host and start time

A call is checked whole (ids, hyperparameters, checkpoint, log directory) and the env and
model are built before anything in the log directory is created or opened, so a mistake leaves
an earlier run's files as they were.  Nothing of a run is lost or silently replaced
(:mod:`agents.train_safety`): one run at a time holds a log directory (a second is refused,
naming the first's process); a log directory that holds a run (its model, config or
checkpoints) is refused unless the call resumes it or says ``overwrite``; SIGTERM, SIGHUP and
Ctrl-C end training at the next step with a checkpoint to resume from (:class:`TrainStopped`);
every model, checkpoint, config and evaluation log is written atomically.

Loading a checkpoint to resume never unpickles anything from it
(:func:`agents.sb3_agent.safe_custom_objects`); a SAC replay buffer is read from npz without
pickle, and SB3's pickled ``.pkl`` buffers only when trusted (``trust_replay_buffer``).

Resuming (``resume=CHECKPOINT``): the budget is the total step count, the checkpoint's steps
included.  The algorithm's arguments are the checkpoint's; ``overrides`` may change those SB3
re-applies to a loaded model (:data:`RESUMABLE`), any other is refused.  The run settings
(``n_envs``, ``env_kwargs``) and the run settings apply as for a new run.  Resuming
into a log directory that holds the same run continues its monitor, progress and evaluation
logs, and keeps its earlier config under ``previous_runs`` in config.yml.

SB3 and torch are imported only inside the functions (they are the ``train`` extra).
"""

from __future__ import annotations

import copy
import json
import math
import re
import zipfile
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any

import yaml

from agents.train_safety import (
    RunLock,
    check_unlocked,
    earlier_run,
    find_replay_buffer,
    load_replay_buffer,
)
from fetch_env.errors import env_error_line

ALGOS: tuple[str, ...] = ("ppo", "sac")
# Keys of the YAML files that are not arguments of the SB3 constructor: rl_zoo3's, which
# its ExperimentManager takes out before it builds the model (so they mean the same there).
RUN_KEYS: tuple[str, ...] = ("n_envs", "n_timesteps", "policy", "env_kwargs")
# rl_zoo3's other YAML keys, which food-fetch train does not implement: refused by name.
ZOO_ONLY: tuple[str, ...] = ("normalize", "frame_stack", "env_wrapper", "vec_env_wrapper",
                             "callback", "monitor_kwargs", "noise_type", "noise_std")
# The run settings, by the names of the ``train()`` arguments and of rl_zoo3's train flags.
SETTINGS: dict[str, str] = {"eval_freq": "--eval-freq", "n_eval_episodes": "--eval-episodes",
                            "save_freq": "--save-freq"}
# Their earlier names as hyperparameters: still taken in ``overrides`` (``--hyperparams``),
# never in a YAML file, where rl_zoo3 would pass them to SB3's constructor (a TypeError).
LEGACY: dict[str, str] = {"eval_freq": "eval_freq", "n_eval_episodes": "n_eval_episodes",
                          "checkpoint_freq": "save_freq"}
DEFAULT_EVAL_EPISODES = 20
EVALS_PER_RUN = 4  # default eval and checkpoint frequency: a quarter of the budget
EVAL_SEED_OFFSET = 1_000_003  # eval scenes never coincide with training scenes
MAX_ENVS = 64  # DummyVecEnv steps the envs one after another: more than this is a typo
INFO_KEYS: tuple[str, ...] = ("fetch_rate", "max_log_strain", "is_success")  # monitor columns
# Constructor arguments that food-fetch train sets itself, and the option that sets them.
RESERVED: dict[str, str] = {"env": "--env", "seed": "--seed", "verbose": "--verbose",
                            "device": "always cpu", "tensorboard_log": "--log-dir",
                            "_init_setup_model": "internal to SB3"}
# Arguments SB3 re-applies when it loads a model (``load(**kwargs)`` then ``_setup_model``)
# without changing the network or the optimizer state it restores: the only ones an override
# may change on resume (policy_kwargs, SAC's ent_coef or buffer_size would not load).
RESUMABLE: dict[str, tuple[str, ...]] = {
    "ppo": ("learning_rate", "n_steps", "batch_size", "n_epochs", "gamma", "gae_lambda",
            "clip_range", "clip_range_vf", "normalize_advantage", "ent_coef", "vf_coef",
            "max_grad_norm", "target_kl"),
    "sac": ("learning_rate", "batch_size", "learning_starts", "train_freq", "gradient_steps",
            "gamma", "tau", "target_update_interval"),
}
# (integer?, low, high, low excluded?) of the run keys and of the SB3 arguments whose range
# SB3 checks late or not at all (a loaded model skips the constructor's checks).
Range = tuple[bool, float | None, float | None, bool]
RANGES: dict[str, Range] = {
    "n_envs": (True, 1, MAX_ENVS, False), "n_timesteps": (True, 1, None, False),
    # the run settings under their earlier names (``--hyperparams eval_freq=...``)
    "eval_freq": (True, 0, None, False), "n_eval_episodes": (True, 1, None, False),
    "checkpoint_freq": (True, 0, None, False),
    "learning_rate": (False, 0, None, True), "n_steps": (True, 1, None, False),
    "n_epochs": (True, 1, None, False), "gamma": (False, 0, 1, False),
    "gae_lambda": (False, 0, 1, False), "clip_range": (False, 0, None, True),
    "clip_range_vf": (False, 0, None, True), "vf_coef": (False, 0, None, False),
    "max_grad_norm": (False, 0, None, True), "target_kl": (False, 0, None, True),
    "buffer_size": (True, 1, None, False), "learning_starts": (True, 0, None, False),
    "gradient_steps": (True, -1, None, False), "tau": (False, 0, 1, False),
    "target_update_interval": (True, 1, None, False), "sde_sample_freq": (True, -1, None, False),
    "stats_window_size": (True, 1, None, False),
}
ALGO_RANGES: dict[str, dict[str, Range]] = {
    "ppo": {"batch_size": (True, 2, None, False),  # SB3 asserts batch_size > 1
            "ent_coef": (False, 0, None, False)},
    "sac": {"batch_size": (True, 1, None, False),
            "ent_coef": (False, 0, None, False)},  # or "auto", "auto_<start>": SB3 reads those
}
NULLABLE: tuple[str, ...] = ("clip_range_vf", "target_kl")  # None switches them off
FLAGS: tuple[str, ...] = ("normalize_advantage", "use_sde", "optimize_memory_usage",
                          "use_sde_at_warmup")
# SB3 wants Python objects (a class, an ActionNoise) here, which a YAML value cannot be.
OBJECTS: tuple[str, ...] = ("action_noise", "rollout_buffer_class", "replay_buffer_class")


class TrainError(Exception):
    """A bad training request (unknown id, missing file, bad hyperparameter, a log directory
    in use or holding a run): one line."""


class TrainStopped(KeyboardInterrupt):
    """Training ended early on SIGTERM, SIGHUP or SIGINT, after saving ``checkpoint`` (and
    SAC's replay buffer beside it) and the model so far: ``resume=checkpoint`` continues."""

    def __init__(self, signame: str, signum: int, steps: int, total: int, checkpoint: Path,
                 log_dir: Path) -> None:
        self.signame, self.signum, self.steps, self.total = signame, signum, steps, total
        self.checkpoint, self.log_dir = checkpoint, log_dir
        super().__init__(self.one_line())

    def one_line(self) -> str:
        return (f"stopped by {self.signame} at step {self.steps} of {self.total}; saved "
                f"{self.checkpoint}: continue with --resume {self.checkpoint} --log-dir "
                f"{self.log_dir} --timesteps {self.total}")


class _Loader(yaml.SafeLoader):
    """PyYAML reads ``1e-3`` (no dot) as a string; YAML 1.2 and every user read a float."""


_Loader.add_implicit_resolver(
    "tag:yaml.org,2002:float", re.compile(r"^[-+]?(?:\d+\.?\d*|\.\d+)[eE][-+]?\d+$"),
    list("-+0123456789."))


def _yaml(text: str) -> Any:
    return yaml.load(text, Loader=_Loader)  # _Loader is a SafeLoader


def _short(value: Any, width: int = 60) -> str:
    text = repr(value)
    return text if len(text) <= width else text[:width - 3] + "..."


def _first_line(exc: BaseException) -> str:
    lines = str(exc).strip().splitlines()
    return lines[0] if lines else type(exc).__name__


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
        table = _yaml(path.read_text())
    except OSError as exc:
        raise TrainError(f"cannot read hyperparameter file {str(path)!r}: {exc.strerror}") from None
    except UnicodeDecodeError:
        raise TrainError(f"hyperparameter file {str(path)!r} is not a text file") from None
    except yaml.YAMLError as exc:
        raise TrainError(f"hyperparameter file {str(path)!r} is not valid YAML: "
                         f"{str(exc).splitlines()[0]}") from None
    if not isinstance(table, dict):
        raise TrainError(f"hyperparameter file {str(path)!r} must map environment ids to "
                         f"hyperparameters (FoodFetch-Block-v0: {{...}}), got {_short(table)}")
    if env_id not in table:
        raise TrainError(f"no {algo} hyperparameters for {env_id!r} in {str(path)!r} "
                         f"(ids there: {', '.join(map(str, table)) or 'none'})")
    block = {} if table[env_id] is None else table[env_id]  # an empty block: all defaults
    if not isinstance(block, dict):
        raise TrainError(f"the {env_id} entry of {str(path)!r} must be a mapping of "
                         f"hyperparameters (key: value), got {_short(block)}")
    bad = [k for k in block if not isinstance(k, str)]
    if bad:
        raise TrainError(f"hyperparameter names in {str(path)!r} must be text, got {bad[0]!r}")
    moved = [k for k in LEGACY if k in block]
    if moved:  # the file must stay one that python -m rl_zoo3.train --conf-file accepts
        raise TrainError(f"{moved[0]} in {str(path)!r} is a run setting, not an rl_zoo3 "
                         f"hyperparameter (rl_zoo3 would pass it to SB3's {algo.upper()}): "
                         f"remove it and give {SETTINGS[LEGACY[moved[0]]]} instead")
    hp = copy.deepcopy(block)
    hp.update(copy.deepcopy(overrides or {}))
    return hp


def parse_override(text: str) -> tuple[str, Any]:
    """``key=value`` with the value read as YAML (``learning_rate=1e-3``, ``net_arch=[32]``)."""
    key, eq, value = text.partition("=")
    if not eq or not key.strip():
        raise TrainError(f"hyperparameter override must be key=value, got {text!r}")
    try:
        return key.strip(), _yaml(value)
    except yaml.YAMLError:
        raise TrainError(f"cannot read the value of override {text!r}") from None


def _check_range(algo: str, key: str, value: Any) -> None:
    if key in FLAGS and not isinstance(value, bool):
        raise TrainError(f"bad hyperparameter {key}={_short(value)}: must be true or false")
    if key in OBJECTS and value is not None:
        raise TrainError(f"bad hyperparameter {key}={_short(value)}: must be null (SB3 wants "
                         "a Python object here, which food-fetch train cannot read from YAML)")
    if algo == "sac" and key == "ent_coef" and isinstance(value, str):
        return  # "auto" or "auto_<start>", read (and checked) by SB3
    spec = ALGO_RANGES[algo].get(key, RANGES.get(key))
    if spec is None or (value is None and key in NULLABLE):
        return
    integer, low, high, open_low = spec
    ok = (isinstance(value, int) if integer else isinstance(value, (int, float)))
    # (an int is finite, and math.isfinite would overflow on one past a float's range)
    ok = ok and not isinstance(value, bool) and (isinstance(value, int)
                                                 or math.isfinite(value))
    if ok:
        ok = (value > low if open_low else value >= low) if low is not None else True
        ok = ok and (high is None or value <= high)
    if not ok:
        kind = "an integer" if integer else "a number"
        if high is not None:
            bounds = f"in {'(' if open_low else '['}{low:g}, {high:g}]"
        else:
            bounds = f"{'>' if open_low else '>='} {low:g}"
        none = " or null" if key in NULLABLE else ""
        raise TrainError(f"bad hyperparameter {key}={_short(value)}: must be {kind} "
                         f"{bounds}{none}")


def _check_train_freq(value: Any) -> None:
    # SAC takes an int (steps) or [n, "step" | "episode"]
    ok = isinstance(value, int) and not isinstance(value, bool) and value >= 1
    if isinstance(value, list) and len(value) == 2:
        n, unit = value
        ok = (isinstance(n, int) and not isinstance(n, bool) and n >= 1
              and unit in ("step", "episode"))
    if not ok:
        raise TrainError(f"bad hyperparameter train_freq={_short(value)}: must be an integer "
                         ">= 1 or [n, step|episode]")


@dataclass
class _Plan:
    """A checked training request: everything decided before any file is touched."""

    algo: str
    env_id: str
    total: int
    seed: int
    log_dir: Path
    ctor: dict[str, Any]            # SB3 constructor arguments (new run)
    run: dict[str, Any]             # RUN_KEYS as given (recorded in config.yml)
    settings: dict[str, int]        # SETTINGS: eval_freq, n_eval_episodes, save_freq
    source: str                     # where the hyperparameters came from, for messages
    overrides: dict[str, Any]
    resume: Path | None = None
    done: int = 0                   # the checkpoint's steps
    resume_kwargs: dict[str, Any] = field(default_factory=dict)
    previous_runs: list[Any] = field(default_factory=list)
    monitor_starts: dict[int, float] = field(default_factory=dict)  # monitor logs to continue
    eval_history: dict[str, list[Any]] | None = None
    append_progress: bool = False
    data: dict[str, Any] = field(default_factory=dict)  # the checkpoint's (JSON) data
    replay_buffer: Path | None = None    # SAC's buffer beside the checkpoint
    overwrite: bool = False             # remove an earlier run's files first

    @property
    def n_envs(self) -> int:
        return int(self.run.get("n_envs", 1))

    @property
    def env_kwargs(self) -> dict[str, Any]:
        return dict(self.run.get("env_kwargs") or {})

    @property
    def eval_freq(self) -> int:
        return self.settings["eval_freq"]

    @property
    def n_eval_episodes(self) -> int:
        return self.settings["n_eval_episodes"]

    @property
    def save_freq(self) -> int:
        return self.settings["save_freq"]


def _checkpoint(path: str | Path, algo: str | None) -> tuple[str, dict[str, Any]]:
    """The checkpoint's algorithm and metadata, checked against ``algo`` (None: any)."""
    from agents.sb3_agent import ModelLoadError, algo_of_data, model_data

    if not Path(path).is_file():
        raise TrainError(f"checkpoint not found: {str(path)!r}")
    try:
        data = model_data(path)
    except ModelLoadError as exc:
        raise TrainError(f"checkpoint {exc}") from None
    found = algo_of_data(data)
    steps = data.get("num_timesteps")
    if found is None or not isinstance(steps, int) or steps < 0:
        raise TrainError(f"checkpoint {str(path)!r} is not a valid PPO or SAC model")
    if algo is not None and algo != found:
        raise TrainError(f"checkpoint {str(path)!r} is a {found} model, not {algo}: "
                         f"use --algo {found} (or leave --algo out)")
    return found, data


def _read_config(path: Path) -> dict[str, Any] | None:
    try:
        cfg = yaml.safe_load(path.read_text())
    except (OSError, UnicodeDecodeError, yaml.YAMLError):
        return None
    return cfg if isinstance(cfg, dict) else None


def _monitor_start(path: Path) -> float | None:
    """``t_start`` of a monitor log to continue; None when there is none (or it is empty)."""
    if not path.is_file() or path.stat().st_size == 0:
        return None
    try:
        with open(path) as fh:
            head, columns = fh.readline(), fh.readline()
        start = float(json.loads(head[1:])["t_start"]) if head.startswith("#") else None
    except (OSError, UnicodeDecodeError, ValueError, KeyError, TypeError):
        start = None
    # Rows appended under other columns would corrupt the CSV.
    if start is None or columns.strip().split(",") != ["r", "l", "t", *INFO_KEYS]:
        raise TrainError(f"{str(path)!r} is not a food-fetch train monitor log, so the resumed "
                         "run cannot continue it: move it away or use another --log-dir")
    return start


def _eval_history(path: Path, n_eval_episodes: int) -> dict[str, list[Any]] | None:
    """The evaluations of an earlier run, which the resumed EvalCallback continues."""
    if not path.is_file():
        return None
    import numpy as np

    try:
        with np.load(path, allow_pickle=False) as npz:
            hist = {k: npz[k].tolist() for k in npz.files}
    except (OSError, ValueError, EOFError, zipfile.BadZipFile):
        hist = {}
    results = hist.get("results")
    if ("timesteps" not in hist or "ep_lengths" not in hist or not isinstance(results, list)
            or not all(isinstance(r, list) for r in results)):
        raise TrainError(f"{str(path)!r} is not an evaluation log, so the resumed run cannot "
                         "continue it: move it away or use another --log-dir")
    if results and len(results[0]) != n_eval_episodes:
        # EvalCallback saves one array: rows of another length would not stack.
        raise TrainError(f"bad run setting n_eval_episodes={n_eval_episodes}: the earlier "
                         f"evaluations in {str(path)!r} have {len(results[0])} episodes each; "
                         f"keep that (--eval-episodes {len(results[0])}) or use another "
                         "--log-dir")
    return hist


def _check_hyperparams(algo: str, run: dict[str, Any], ctor: dict[str, Any]) -> None:
    """The run keys (this project's own: checked here, not by SB3) and the constructor's
    (each an argument of SB3's class, none that ``food-fetch train`` sets itself)."""
    import inspect

    from stable_baselines3 import PPO, SAC

    for key, value in run.items():
        _check_range(algo, key, value)
    cls = {"ppo": PPO, "sac": SAC}[algo]
    policy = run.get("policy", "MlpPolicy")
    if policy not in cls.policy_aliases:
        raise TrainError(f"bad hyperparameter policy={_short(policy)}: choose from "
                         f"{', '.join(cls.policy_aliases)}")
    env_kwargs = run.get("env_kwargs")
    if env_kwargs is not None and (not isinstance(env_kwargs, dict)
                                   or not all(isinstance(k, str) for k in env_kwargs)):
        raise TrainError(f"bad hyperparameter env_kwargs={_short(env_kwargs)}: must be a "
                         "mapping of env arguments, e.g. {estimator: none}")

    args = set(inspect.signature(cls.__init__).parameters) - {"self", "policy"}
    for key, value in ctor.items():
        if key in ZOO_ONLY:
            raise TrainError(f"hyperparameter {key!r} is one of rl_zoo3's that food-fetch train "
                             "does not implement: train with python -m rl_zoo3.train instead")
        if key in RESERVED:
            raise TrainError(f"bad hyperparameter {key}={_short(value)}: food-fetch train sets "
                             f"it ({RESERVED[key]})")
        if key not in args:
            raise TrainError(f"unknown {algo} hyperparameter {key!r} (neither an argument of "
                             f"SB3's {cls.__name__} nor one of {', '.join(RUN_KEYS)})")
        _check_range(algo, key, value)
        if algo == "sac" and key == "train_freq":
            _check_train_freq(value)


def _resume_state(algo: str, run: dict[str, Any], ctor: dict[str, Any],
                  resume: str | Path | None, data: dict[str, Any], overrides: dict[str, Any]
                  ) -> tuple[int, dict[str, Any]]:
    """Steps already done and the hyperparameters a resumed run may change; PPO's rollout
    (``n_steps x n_envs >= 2``) checked for new and resumed runs alike."""
    done = 0
    resume_kwargs: dict[str, Any] = {}
    if resume is not None:
        done = int(data["num_timesteps"])
        fixed = [k for k in overrides if k in ctor and k not in RESUMABLE[algo]]
        fixed += ["policy"] if "policy" in overrides else []
        if fixed:
            raise TrainError(f"cannot change {fixed[0]} on --resume (the checkpoint's is kept); "
                             f"{algo} resumes with new {', '.join(RESUMABLE[algo])} only")
        resume_kwargs = {k: overrides[k] for k in overrides if k in ctor}
    if algo == "ppo":
        n_steps = ctor.get("n_steps", 2048) if resume is None else \
            resume_kwargs.get("n_steps", data.get("n_steps", 2048))
        n_envs = int(run.get("n_envs", 1))
        if isinstance(n_steps, int) and n_steps * n_envs < 2:  # SB3 asserts it for new runs
            whose = (" (the checkpoint's: override n_steps or n_envs)"
                     if resume is not None and "n_steps" not in overrides else "")
            raise TrainError(f"bad hyperparameter n_steps={n_steps}: n_steps x n_envs must be "
                             f">= 2, got {n_steps} x {n_envs}{whose}")
    return done, resume_kwargs


def _run_settings(given: dict[str, int | None], legacy: dict[str, Any], algo: str,
                  total: int) -> dict[str, int]:
    """The run settings: the arguments given, else the earlier hyperparameter names in the
    overrides, else the defaults (a quarter of the budget; 20 episodes).  As in rl_zoo3, a
    frequency <= 0 switches evaluation or checkpoints off."""
    settings = dict(given)
    for old, value in legacy.items():
        _check_range(algo, old, value)
        new = LEGACY[old]
        if settings.get(new) is not None and settings[new] != value:
            raise TrainError(f"{SETTINGS[new]} {settings[new]} and --hyperparams "
                             f"{old}={_short(value)} disagree: give {SETTINGS[new]} only")
        settings[new] = value
    every = max(1, math.ceil(total / EVALS_PER_RUN))
    out = {"eval_freq": every, "save_freq": every, "n_eval_episodes": DEFAULT_EVAL_EPISODES}
    for key, flag in SETTINGS.items():
        value = settings.get(key)
        if value is None:
            continue
        episodes = key == "n_eval_episodes"
        if (not isinstance(value, int) or isinstance(value, bool)
                or (episodes and value < 1)):
            raise TrainError(f"bad run setting {flag} {_short(value)}: must be an integer"
                             f"{' >= 1' if episodes else ''}")
        out[key] = value if episodes else max(0, value)
    return out


def _plan(algo: str | None, env_id: str, timesteps: int | None, seed: int, log_dir: Path,
          resume: str | Path | None, hyperparams_file: str | Path | None,
          overrides: dict[str, Any], eval_enabled: bool,
          given: dict[str, int | None] | None = None, overwrite: bool = False,
          trust_replay_buffer: bool = False, quasi_static: bool = False) -> _Plan:
    """Check the whole request; reads files, writes none.  ``quasi_static``: the env's
    validated quasi-static setting under the hyperparameters' ``env_kwargs``
    (:func:`fetch_env.quasi_static.quasi_static_kwargs`; a kwarg they give wins)."""
    ids = env_ids()
    if env_id not in ids:
        raise TrainError(f"unknown environment id {env_id!r}; choose from {', '.join(ids)}")
    if algo is not None and algo not in ALGOS:
        raise TrainError(f"unknown algorithm {algo!r}; choose from {', '.join(ALGOS)}")
    data: dict[str, Any] = {}
    if resume is not None:
        algo, data = _checkpoint(resume, algo)
    algo = algo or "ppo"
    overrides = dict(overrides)
    legacy = {k: overrides.pop(k) for k in LEGACY if k in overrides}
    hp = load_hyperparams(algo, env_id, hyperparams_file, overrides)
    if quasi_static:
        from fetch_env.quasi_static import quasi_static_kwargs

        given_kwargs = hp.get("env_kwargs") or {}
        if isinstance(given_kwargs, dict):  # (anything else: refused by name below)
            hp["env_kwargs"] = {**quasi_static_kwargs(env_id), **given_kwargs}
    run = {k: hp.pop(k) for k in RUN_KEYS if k in hp}
    ctor = hp
    source = str(hyperparams_file or hyperparams_path(algo))

    _check_hyperparams(algo, run, ctor)
    done, resume_kwargs = _resume_state(algo, run, ctor, resume, data, overrides)

    total = timesteps if timesteps is not None else run.get("n_timesteps", 10_000)
    if not isinstance(total, int) or isinstance(total, bool) or total < 1:
        raise TrainError(f"--timesteps must be an integer >= 1, got {total!r}")
    if resume is not None and total <= done:
        raise TrainError(f"--timesteps {total} is not past the checkpoint's {done} steps "
                         "(--timesteps counts them): nothing to train")

    settings = _run_settings(dict(given or {}), legacy, algo, total)
    plan = _Plan(algo=algo, env_id=env_id, total=total, seed=seed, log_dir=log_dir, ctor=ctor,
                 run=run, settings=settings, source=source, overrides=dict(overrides),
                 resume=Path(resume) if resume is not None else None, done=done,
                 resume_kwargs=resume_kwargs, data=data, overwrite=overwrite)
    _plan_log_dir(plan, eval_enabled, trust_replay_buffer)
    return plan


def _plan_log_dir(plan: _Plan, eval_enabled: bool, trust_replay_buffer: bool) -> None:
    """The log dir: free (no live run holds its lock), and holding no earlier run unless
    this one resumes it or overwrites it; SAC's replay buffer beside the checkpoint, loaded
    only from npz or when trusted (a pickle can run code)."""
    d = plan.log_dir
    if d.exists() and not d.is_dir():
        raise TrainError(f"--log-dir {str(d)!r} is a file, not a directory")
    if plan.resume is not None and plan.overwrite:
        raise TrainError("--resume continues the run in --log-dir and --overwrite replaces "
                         "it: give one of them")
    if d.is_dir():
        check_unlocked(d)
        found = earlier_run(d)
        if found is not None and plan.resume is None and not plan.overwrite:
            raise TrainError(f"--log-dir {str(d)!r} already holds a run ({found}): "
                             "--overwrite replaces it, --resume CHECKPOINT continues it, or "
                             "choose another --log-dir")
        if plan.resume is not None:
            _plan_continuation(plan, eval_enabled)
    if plan.resume is not None and plan.algo == "sac":
        plan.replay_buffer = find_replay_buffer(plan.resume)
        if (plan.replay_buffer is not None and plan.replay_buffer.suffix == ".pkl"
                and not trust_replay_buffer):
            raise TrainError(f"the replay buffer {str(plan.replay_buffer)!r} is a pickle, "
                             "which can run code when loaded (food-fetch train writes .npz): "
                             "--trust-replay-buffer loads it if you trust its source; or move "
                             "it away to resume with an empty buffer")


def _plan_continuation(plan: _Plan, eval_enabled: bool) -> None:
    """Resuming into a log dir that holds a run: continue its logs, never overwrite them."""
    d = plan.log_dir
    prev = _read_config(d / "config.yml")
    if prev is not None:
        if (prev.get("algo"), prev.get("env")) != (plan.algo, plan.env_id):
            raise TrainError(f"--log-dir {str(d)!r} holds a {prev.get('algo')} run on "
                             f"{prev.get('env')}: resume into another --log-dir")
        finished = prev.get("finished_steps")
        if isinstance(finished, int) and finished > plan.done:
            # Continuing from an older checkpoint would interleave two histories (and
            # overwrite the later checkpoints).
            raise TrainError(f"--log-dir {str(d)!r} already holds {finished} steps, past the "
                             f"checkpoint's {plan.done}: resume into another --log-dir")
        earlier = prev.pop("previous_runs", None)
        plan.previous_runs = [*(earlier if isinstance(earlier, list) else []), prev]
    for i in range(plan.n_envs):
        start = _monitor_start(d / "monitor" / f"{i}.monitor.csv")
        if start is not None:
            plan.monitor_starts[i] = start
    progress = d / "progress.csv"
    plan.append_progress = progress.is_file() and progress.stat().st_size > 0
    if eval_enabled and plan.eval_freq > 0:
        plan.eval_history = _eval_history(d / "eval" / "evaluations.npz", plan.n_eval_episodes)


def _blame(exc: BaseException, plan: _Plan) -> str:
    """The hyperparameters an SB3 error names, else the user's overrides, else the file."""
    text = str(exc).lower()
    keys = [k for k in plan.ctor if k.lower() in text or k.replace("_", " ") in text]
    keys = keys or [k for k in plan.overrides if k in plan.ctor]
    if keys:
        return " ".join(f"{k}={_short(plan.ctor[k])}" for k in keys)
    return f"from {plan.source!r}"


def _build(plan: _Plan, verbose: int, eval_enabled: bool) -> tuple[Any, Any, Any]:
    """The training env, the model and the eval env (or None), built from the user's input
    with no file written: the monitors get their files in :func:`agents.train_run.run`."""
    from stable_baselines3 import PPO, SAC
    from stable_baselines3.common.env_util import make_vec_env
    from stable_baselines3.common.utils import set_random_seed

    set_random_seed(plan.seed)
    # make_vec_env asks for rgb_array frames by default: no rendering while training.
    env_kwargs = {"render_mode": None, **plan.env_kwargs}
    envs: list[Any] = []
    try:
        envs.append(make_vec_env(plan.env_id, n_envs=plan.n_envs, seed=plan.seed,
                                 env_kwargs=env_kwargs,
                                 monitor_kwargs={"info_keywords": INFO_KEYS}))
        if eval_enabled and plan.eval_freq > 0:
            envs.append(make_vec_env(plan.env_id, n_envs=1, seed=plan.seed + EVAL_SEED_OFFSET,
                                     env_kwargs=env_kwargs))
    except (TypeError, ValueError) as exc:  # the env's own check of env_kwargs
        for e in envs:
            e.close()
        raise TrainError(f"bad hyperparameter env_kwargs={_short(plan.env_kwargs)}: "
                         f"{env_error_line(exc)}") from None
    env, eval_env = envs[0], (envs[1] if len(envs) > 1 else None)

    cls = {"ppo": PPO, "sac": SAC}[plan.algo]
    try:
        if plan.resume is None:
            try:
                model = cls(plan.run.get("policy", "MlpPolicy"), env, seed=plan.seed,
                            device="cpu", verbose=verbose, **plan.ctor)
            except (TypeError, ValueError, AssertionError, KeyError, RuntimeError) as exc:
                raise TrainError(f"bad {plan.algo} hyperparameters {_blame(exc, plan)}: "
                                 f"{_first_line(exc)}") from None
        else:
            model = _load_checkpoint(plan, cls, env, verbose)
    except TrainError:
        for e in envs:
            e.close()
        raise
    return env, model, eval_env


def _load_checkpoint(plan: _Plan, cls: Any, env: Any, verbose: int) -> Any:
    """The checkpoint as a model on ``env``, nothing in it unpickled: its pickled entries are
    rebuilt from the env, the numbers beside them, the run's config and this run's
    hyperparameters; SAC's replay buffer from npz (or a trusted pickle)."""
    from agents.sb3_agent import ModelLoadError, config_near, safe_custom_objects

    assert plan.resume is not None
    name = repr(str(plan.resume))
    try:
        custom = safe_custom_objects(
            plan.data, plan.algo, f"checkpoint {name}",
            observation_space=env.observation_space, action_space=env.action_space,
            settings={**plan.ctor, **config_near(plan.resume)}, for_training=True)
        model = cls.load(str(plan.resume), env=env, device="cpu", verbose=verbose,
                         custom_objects=custom, **plan.resume_kwargs)
    except ModelLoadError as exc:
        raise TrainError(str(exc)) from None
    except Exception as exc:  # a corrupt or foreign zip: one line, not a traceback
        raise TrainError(f"checkpoint {name} is not a valid {plan.algo} model: "
                         f"{type(exc).__name__}: {_first_line(exc)}") from None
    buf = plan.replay_buffer
    if buf is None:
        return model
    if buf.suffix == ".npz":
        load_replay_buffer(model.replay_buffer, buf)
        return model
    try:  # a .pkl the user said to trust (_plan_log_dir refuses it otherwise)
        model.load_replay_buffer(str(buf))
    except Exception as exc:  # same: a file the user pointed at
        raise TrainError(f"cannot load the replay buffer {str(buf)!r}: "
                         f"{type(exc).__name__}: {_first_line(exc)}") from None
    if model.replay_buffer.n_envs != plan.n_envs:
        raise TrainError(f"bad hyperparameter n_envs={plan.n_envs}: the replay "
                         f"buffer {str(buf)!r} holds {model.replay_buffer.n_envs}")
    return model


def train(algo: str | None, env_id: str, timesteps: int | None, seed: int,
          log_dir: str | Path, *, resume: str | Path | None = None,
          hyperparams_file: str | Path | None = None, overrides: dict[str, Any] | None = None,
          progress: bool = True, threads: int = 1, verbose: int = 0, eval_enabled: bool = True,
          command: list[str] | None = None, eval_freq: int | None = None,
          n_eval_episodes: int | None = None, save_freq: int | None = None,
          overwrite: bool = False, trust_replay_buffer: bool = False,
          quasi_static: bool = False) -> Path:
    """Train and save ``log_dir/model.zip``; returns its path.

    ``algo`` None: the checkpoint's algorithm when resuming, else PPO.  ``timesteps`` is the
    total budget (the YAML's ``n_timesteps`` when None), the checkpoint's steps included when
    resuming from ``resume`` (a checkpoint .zip).  PPO collects whole rollouts of
    ``n_steps x n_envs`` steps, so it may stop up to one rollout past the budget.
    ``eval_freq`` and ``save_freq`` (steps; <= 0: off) default to a quarter of the budget,
    ``n_eval_episodes`` to 20; ``overrides`` may also give them as ``eval_freq``,
    ``n_eval_episodes`` and ``checkpoint_freq``.  ``quasi_static``: train on the env's
    validated quasi-static setting (:mod:`fetch_env.quasi_static`; ``env_kwargs`` given in
    the hyperparameters override it), recorded with them in config.yml.

    ``log_dir`` is locked for the run (TrainError if another run holds it); a ``log_dir``
    holding an earlier run is refused unless ``resume`` continues it or ``overwrite`` replaces
    it (its model, config, logs, evaluations and checkpoints are deleted once the new run is
    built).  SIGTERM, SIGHUP or SIGINT end training at the next step: the model, a checkpoint
    (with SAC's replay buffer) and the config are saved, then :class:`TrainStopped` is raised.
    A SAC replay buffer saved by SB3 as a pickle is loaded only with ``trust_replay_buffer``.
    """
    import torch

    log_dir = Path(log_dir)
    given = {"eval_freq": eval_freq, "n_eval_episodes": n_eval_episodes, "save_freq": save_freq}
    plan = _plan(algo, env_id, timesteps, seed, log_dir, resume, hyperparams_file,
                 dict(overrides or {}), eval_enabled, given, overwrite=overwrite,
                 trust_replay_buffer=trust_replay_buffer, quasi_static=quasi_static)
    torch.set_num_threads(max(1, int(threads)))
    env, model, eval_env = _build(plan, verbose, eval_enabled)
    # Only now, with everything checked and built, does the log dir change.
    try:
        lock = RunLock.acquire(log_dir, command)
    except (TrainError, OSError) as exc:
        for e in (env, eval_env):
            if e is not None:
                e.close()
        if isinstance(exc, TrainError):
            raise
        raise TrainError(f"cannot write to --log-dir {str(log_dir)!r}: {exc.strerror}") from None
    from agents.train_run import run  # (it imports this module)

    try:
        return run(plan, env, model, eval_env, progress=progress, threads=threads,
                   verbose=verbose, eval_enabled=eval_enabled, command=command)
    finally:
        lock.release()
