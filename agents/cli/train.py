"""``food-fetch train``: PPO or SAC on a FoodFetch environment (Stable-Baselines3)."""

from __future__ import annotations

import argparse
from pathlib import Path

from agents.cli.common import (
    DEFAULT_ENV,
    UsageError,
    integer,
    positive_int,
    require_extra,
    seed,
)

HELP = "train PPO or SAC on a FoodFetch environment (Stable-Baselines3 or RLlib)"
DESCRIPTION = ("Train PPO or SAC with the hyperparameters shipped for the environment "
               "id (agents/hyperparams/<algo>.yml, which python -m rl_zoo3.train --conf-file "
               "reads as they are). Writes "
               "model.zip, config.yml (to repeat the run), progress.csv, monitor/, eval/ "
               "(periodic evaluation, best model) and checkpoints/ under --log-dir, which one "
               "run at a time holds (a second is refused, naming the first's process). A "
               "--log-dir holding a run is refused unless --resume continues it or "
               "--overwrite replaces it. SIGTERM, SIGHUP or Ctrl-C stop training at the next "
               "step, save a checkpoint (SAC: with its replay buffer) and print the --resume "
               "command that continues it; the exit code is 128 + the signal's number. Needs "
               "the train extra (stable-baselines3, torch). --backend rllib trains with RLlib "
               "instead, over Ray env runners (the rllib extra).")
ENV_HELP = ("FoodFetch-{Block,Row,TwoRows,Diced}-v0 or -v1, FoodFetch-{Row,TwoRows}-v2, "
            "FoodFetch-TwoRows-v3")


def _log_dir(text: str) -> Path:
    import os

    if not text.strip():  # Path("") is the current directory: say so rather than write there
        raise argparse.ArgumentTypeError(f"not a directory name: {text!r}")
    p = Path(text)
    probe = p
    while not probe.exists():
        if probe.parent == probe:
            break
        probe = probe.parent
    if probe.exists() and (not probe.is_dir() or not os.access(probe, os.W_OK)):
        raise argparse.ArgumentTypeError(f"cannot write to {text!r}")
    return p


# Options of the SB3 backend that the RLlib one does not take (refused, one line).
SB3_ONLY = ("resume", "hyperparams", "eval_freq", "eval_episodes", "no_eval",
            "trust_replay_buffer", "verbose")


def _cmd_train_rllib(args: argparse.Namespace) -> int:
    """``--backend rllib``: checked, trained, the policy exported (agents.rllib_train)."""
    import sys

    require_extra("train --backend rllib", "rllib")
    given = [o for o in SB3_ONLY if getattr(args, o) not in (None, False, [], 0)]
    if given:
        raise UsageError(f"food-fetch train: --{given[0].replace('_', '-')} is not taken with "
                         "--backend rllib")
    from agents.ray_runner import RaySetupError, check_address
    from agents.rllib_train import RLlibPlan, RLlibStopped, load_settings, train_rllib
    from agents.train import TrainError

    algo = args.algo or "ppo"
    try:
        address = check_address(args.ray)
        settings = load_settings(algo, args.env, Path(args.hyperparams_file)
                                 if args.hyperparams_file else None)
        timesteps = args.timesteps or int(settings.get("n_timesteps", 1000))
        save_freq = args.save_freq if args.save_freq is not None else max(timesteps // 4, 1)
        plan = RLlibPlan(algo, args.env, timesteps, args.seed, args.log_dir, args.env_runners,
                         address, save_freq, settings, _quasi_static(args))
        policy = train_rllib(plan, overwrite=args.overwrite, progress=not args.no_progress,
                             command=["food-fetch", *sys.argv[1:]])
    except (TrainError, RaySetupError) as exc:
        raise UsageError(f"food-fetch train: {exc}") from None
    except RLlibStopped as exc:
        print(f"food-fetch train: {exc.one_line()}", file=sys.stderr)
        return 128 + exc.signum
    print(f"saved policy      {policy}")
    print(f"checkpoints       {args.log_dir / 'checkpoints'}")
    print(f"evaluate with     food-fetch evaluate --agent {policy} --env {args.env}")
    return 0


def _quasi_static(args: argparse.Namespace) -> dict[str, float]:
    """The env kwargs ``--quasi-static`` asks for (none without it)."""
    if not args.quasi_static:
        return {}
    from fetch_env.quasi_static import quasi_static_kwargs

    return quasi_static_kwargs(args.env)


def _resumed_env(checkpoint: str) -> str | None:
    """The env id of the run a checkpoint or model belongs to (its ``config.yml``, beside
    the model or one folder up from ``checkpoints/``), or None where there is none."""
    try:
        import yaml
    except ImportError:  # no train extra: the command says so next
        return None
    here = Path(checkpoint).parent
    for folder in (here, here.parent):
        try:
            config = yaml.safe_load((folder / "config.yml").read_text())
        except (OSError, yaml.YAMLError):
            continue
        if isinstance(config, dict) and isinstance(config.get("env"), str):
            return config["env"]
    return None


def cmd_train(args: argparse.Namespace) -> int:
    if args.env is None:  # --resume continues on the checkpoint's env unless told otherwise
        args.env = (_resumed_env(args.resume) if args.resume else None) or DEFAULT_ENV
    if args.env not in _env_ids():
        raise UsageError(f"food-fetch train: unknown environment id {args.env!r}; choose "
                         f"from {', '.join(_env_ids())}")
    if args.backend == "rllib":
        return _cmd_train_rllib(args)
    if args.env_runners != 1 or args.ray != "local":
        raise UsageError("food-fetch train: --env-runners and --ray need --backend rllib")
    require_extra("train", "train")
    import sys

    from agents.train import TrainError, TrainStopped, parse_override, train

    try:
        overrides = dict(parse_override(t) for t in args.hyperparams)
        # train() checks the whole request and builds the env and model before it creates
        # or opens anything under --log-dir: a mistake leaves an earlier run's files intact.
        out = train(args.algo, args.env, args.timesteps, args.seed, args.log_dir,
                    resume=args.resume, hyperparams_file=args.hyperparams_file,
                    overrides=overrides, progress=not args.no_progress, threads=args.threads,
                    verbose=args.verbose, eval_enabled=not args.no_eval,
                    command=["food-fetch", *sys.argv[1:]], eval_freq=args.eval_freq,
                    n_eval_episodes=args.eval_episodes, save_freq=args.save_freq,
                    overwrite=args.overwrite, trust_replay_buffer=args.trust_replay_buffer,
                    quasi_static=args.quasi_static)
    except TrainError as exc:
        raise UsageError(f"food-fetch train: {exc}") from None
    except TrainStopped as exc:  # the checkpoint is saved: one line and the signal's code
        print(f"food-fetch train: {exc.one_line()}", file=sys.stderr)
        return 128 + exc.signum
    print(f"saved model       {out}")
    print(f"config            {out.parent / 'config.yml'}")
    print(f"evaluate with     food-fetch evaluate --agent {out} --env {args.env}")
    return 0


def _env_ids() -> list[str]:
    from fetch_env import ENV_IDS

    return sorted(ENV_IDS)


def add_options(p: argparse.ArgumentParser) -> None:
    """The options of ``food-fetch train``."""
    p.add_argument("--backend", choices=("sb3", "rllib"), default="sb3",
                   help="sb3: Stable-Baselines3 in this process (default); rllib: RLlib with "
                   "--env-runners Ray actors collecting fetches, on a local Ray instance or "
                   "the cluster at --ray (the rllib extra). RLlib writes policy.npz (what "
                   "evaluate --agent takes), RLlib checkpoints under checkpoints/, "
                   "progress.csv and config.yml; settings from "
                   "agents/hyperparams/rllib_<algo>.yml")
    p.add_argument("--env-runners", type=positive_int, default=1, metavar="N",
                   help="with --backend rllib: env runners, each a Ray actor on one CPU "
                   "(default: 1)")
    p.add_argument("--ray", default="local", metavar="ADDRESS",
                   help="with --backend rllib: 'local' (a Ray instance of --env-runners + 1 "
                   "CPUs, the default), 'auto', HOST:PORT or ray://HOST:PORT")
    p.add_argument("--algo", choices=("ppo", "sac"), default=None,
                   help="algorithm (default: ppo; with --resume, the checkpoint's)")
    p.add_argument("--env", default=None, metavar="ID",
                   help=f"environment id: {ENV_HELP} (default: {DEFAULT_ENV}; with --resume, "
                   "the env of the checkpoint's run, from its config.yml)")
    p.add_argument("--quasi-static", action="store_true",
                   help="train on the id's quasi-static holds and slow clamps "
                   "(fetch_env.quasi_static; env_kwargs in the hyperparameters override "
                   "them): 1.4-2x the fetches per core, outcomes at the simulator's chaos "
                   "floor; evaluate the model on the plain id")
    p.add_argument("--timesteps", type=positive_int, default=None, metavar="N",
                   help="total environment steps (= fetches); default: n_timesteps of the "
                   "YAML. With --resume, N counts the checkpoint's steps too: it trains N "
                   "minus those, and N must exceed them. PPO collects whole rollouts of "
                   "n_steps x n_envs, so it may stop up to one rollout past N")
    p.add_argument("--seed", type=seed, default=0, metavar="S",
                   help="seed of the policy and the training scenes, in [0, 2**32-1] "
                   "(default: 0)")
    p.add_argument("--log-dir", type=_log_dir, default=Path("out/train"), metavar="DIR",
                   help="output directory, created if missing (default: out/train)")
    p.add_argument("--resume", default=None, metavar="CHECKPOINT",
                   help="continue from a saved model or checkpoint .zip (SAC also reloads the "
                   "replay buffer saved next to it). The algorithm's hyperparameters are the "
                   "checkpoint's; --hyperparams may change only those SB3 re-applies on "
                   "loading (e.g. learning_rate, n_steps, batch_size, n_epochs for PPO), "
                   "others are refused; n_envs, env_kwargs and the run settings apply as "
                   "for a new run. "
                   "Resuming into the --log-dir of the same run appends to its monitor, "
                   "progress and evaluation logs. Nothing in the checkpoint is unpickled "
                   "(docs/security.md)")
    p.add_argument("--overwrite", action="store_true",
                   help="replace the run --log-dir holds: its model.zip, config.yml, logs, "
                   "evaluations and checkpoints are deleted once the new run is built "
                   "(without it, a --log-dir holding a run is refused)")
    p.add_argument("--trust-replay-buffer", action="store_true",
                   help="with --resume, load a SAC replay buffer saved as a pickle (.pkl, "
                   "e.g. by SB3 or rl_zoo3), which can run code: only for a file you trust. "
                   "food-fetch train's own buffers (.npz) need no trust")
    p.add_argument("--hyperparams-file", default=None, metavar="YAML",
                   help="use this YAML instead of the shipped one (same layout)")
    p.add_argument("--hyperparams", nargs="*", default=[], metavar="KEY=VALUE",
                   help="override hyperparameters, values read as YAML "
                   "(e.g. learning_rate=1e-3 n_envs=2); n_envs: 1 to 64; n_timesteps: an "
                   "integer >= 1. Also taken here under their earlier names: eval_freq, "
                   "n_eval_episodes, checkpoint_freq (the three options below)")
    # The run settings, named and read as rl_zoo3's train flags (<= 0: off).
    p.add_argument("--eval-freq", type=integer, default=None, metavar="N",
                   help="evaluate every N steps into eval/ (<= 0: never; default: a quarter "
                   "of the budget)")
    p.add_argument("--eval-episodes", type=positive_int, default=None, metavar="N",
                   help="episodes per evaluation (default: 20)")
    p.add_argument("--save-freq", type=integer, default=None, metavar="N",
                   help="checkpoint every N steps into checkpoints/ (<= 0: never; default: a "
                   "quarter of the budget)")
    p.add_argument("--threads", type=positive_int, default=1, metavar="K",
                   help="torch threads (default: 1)")
    p.add_argument("--no-eval", action="store_true", help="skip the periodic evaluation")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.add_argument("--verbose", type=int, choices=(0, 1), default=0,
                   help="1: print SB3's training table (default: 0)")
