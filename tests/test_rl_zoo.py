"""The RL Zoo's conventions hold as they are: the shipped ``agents/hyperparams/*.yml`` are
rl_zoo3 files for every registered id, ``python -m rl_zoo3.train`` trains with them and
``python -m rl_zoo3.enjoy`` replays what it saved (tiny budgets), its models load in
``food-fetch evaluate``, and ``food-fetch train`` takes its run settings as rl_zoo3's flags."""

from __future__ import annotations

import inspect
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml

from agents.train import RESERVED, hyperparams_path
from tests.cli_helpers import assert_one_line_error, run_cli

pytest.importorskip("stable_baselines3")

# The keys rl_zoo3's ExperimentManager takes out of a YAML block before it passes the rest
# to the algorithm's constructor (exp_manager.py: _preprocess_hyperparams and friends).
ZOO_KEYS = {"n_timesteps", "policy", "n_envs", "env_wrapper", "vec_env_wrapper", "normalize",
            "frame_stack", "callback", "env_kwargs", "policy_kwargs", "monitor_kwargs",
            "noise_type", "noise_std"}
ENV = "FoodFetch-Block-v0"
FAST_ENV = ["--env-kwargs", "estimator:'none'"]  # rl_zoo3 reads each value as Python
# Tiny budgets: 8 steps, evaluated and checkpointed every 4 (one episode is one step).
TINY = {"sac": ["--hyperparams", "learning_starts:4", "batch_size:4"],
        "ppo": ["--hyperparams", "n_steps:4", "batch_size:4", "n_epochs:1"]}


def _registered_ids() -> list[str]:
    from fetch_env import ENV_IDS

    return sorted(ENV_IDS)


@pytest.mark.parametrize("algo", ["ppo", "sac"])
def test_shipped_yaml_holds_only_rl_zoo3_keys_for_every_registered_id(algo: str) -> None:
    # Every id fetch_env registers (new ones included) needs a block rl_zoo3 can build.
    from stable_baselines3 import PPO, SAC

    cls = {"ppo": PPO, "sac": SAC}[algo]
    ctor = set(inspect.signature(cls.__init__).parameters) - {"self", "env", *RESERVED}
    table = yaml.safe_load(hyperparams_path(algo).read_text())  # as rl_zoo3 reads it
    for env_id in _registered_ids():
        assert env_id in table, f"{algo}.yml has no block for {env_id}"
        unknown = set(table[env_id]) - ZOO_KEYS - ctor
        assert not unknown, f"{algo}.yml {env_id}: not rl_zoo3 keys: {sorted(unknown)}"
        assert table[env_id]["n_timesteps"] > 0 and table[env_id]["policy"] == "MlpPolicy"


def _run(args: list[str], cwd: Path) -> str:
    proc = subprocess.run([sys.executable, "-m", *args], cwd=cwd, capture_output=True,
                          text=True, timeout=300)
    out = proc.stdout + proc.stderr
    assert proc.returncode == 0, f"{' '.join(args[:3])} exited {proc.returncode}:\n{out[-3000:]}"
    return out


@pytest.mark.parametrize("algo", ["sac", "ppo"])
def test_rl_zoo3_trains_with_the_shipped_yaml_and_enjoy_replays(
        algo: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    conf = str(hyperparams_path(algo))
    _run(["rl_zoo3.train", "--algo", algo, "--env", ENV, "--gym-packages", "fetch_env",
          "--conf-file", conf, "-n", "8", "--log-folder", "logs", "--seed", "1",
          "--eval-freq", "4", "--eval-episodes", "1", "--save-freq", "4", "--num-threads", "1",
          "--verbose", "0", *FAST_ENV, *TINY[algo]], tmp_path)
    run = tmp_path / "logs" / algo / f"{ENV}_1"
    for name in (f"{ENV}.zip", "rl_model_4_steps.zip", "rl_model_8_steps.zip",
                 "evaluations.npz", f"{ENV}/config.yml"):
        assert (run / name).is_file(), name
    with np.load(run / "evaluations.npz") as ev:
        assert ev["timesteps"].tolist() == [4, 8]

    out = _run(["rl_zoo3.enjoy", "--algo", algo, "--env", ENV, "--gym-packages", "fetch_env",
                "-f", "logs", "--no-render", "-n", "3", "--exp-id", "1", "--deterministic",
                "--num-threads", "1"], tmp_path)
    assert "3 Episodes" in out and "Mean reward" in out

    # The zoo's model is an agent of food-fetch evaluate as it is.
    js = tmp_path / "e.json"
    code, _, err = run_cli(["evaluate", "--agent", str(run / f"{ENV}.zip"), "--episodes", "1",
                            "--json", str(js), "--quiet"], capsys)
    assert code == 0, err
    assert json.loads(js.read_text())["agents"][str(run / f"{ENV}.zip")]["episodes"] == 1


def test_food_fetch_train_takes_the_run_settings_as_rl_zoo3_flags(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    log = tmp_path / "run"
    code, _, err = run_cli(["train", "--timesteps", "8", "--seed", "1", "--log-dir", str(log),
                            "--no-progress", "--eval-freq", "4", "--eval-episodes", "1",
                            "--save-freq", "4", "--hyperparams", "n_steps=4", "batch_size=4",
                            "n_epochs=1", "env_kwargs={estimator: none}"], capsys)
    assert code == 0, err
    with np.load(log / "eval/evaluations.npz") as ev:
        assert ev["timesteps"].tolist() == [4, 8] and ev["results"].shape == (2, 1)
    assert sorted(p.name for p in (log / "checkpoints").iterdir()) == [
        "rl_model_4_steps.zip", "rl_model_8_steps.zip"]
    cfg = yaml.safe_load((log / "config.yml").read_text())
    assert cfg["run_settings"] == {"eval_freq": 4, "n_eval_episodes": 1, "save_freq": 4,
                                   "eval": True}
    assert "eval_freq" not in cfg["hyperparams"]


def test_run_settings_default_to_a_quarter_of_the_budget(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    log = tmp_path / "run"
    code, _, err = run_cli(["train", "--timesteps", "8", "--log-dir", str(log), "--no-progress",
                            "--no-eval", "--hyperparams", "n_steps=2", "batch_size=2",
                            "n_epochs=1", "env_kwargs={estimator: none}"], capsys)
    assert code == 0, err
    cfg = yaml.safe_load((log / "config.yml").read_text())
    assert cfg["run_settings"] == {"eval_freq": 2, "n_eval_episodes": 20, "save_freq": 2,
                                   "eval": False}
    assert sorted(p.name for p in (log / "checkpoints").iterdir()) == [
        f"rl_model_{n}_steps.zip" for n in (2, 4, 6, 8)]


@pytest.mark.parametrize("block, argv, fragment", [
    # a YAML food-fetch train accepts is one rl_zoo3 accepts too
    ({"n_timesteps": 8, "eval_freq": 4}, [],
     "eval_freq in '{hp}' is a run setting, not an rl_zoo3 hyperparameter (rl_zoo3 would pass "
     "it to SB3's PPO): remove it and give --eval-freq instead"),
    ({"n_timesteps": 8, "checkpoint_freq": 4}, [], "give --save-freq instead"),
    ({"n_timesteps": 8, "normalize": True}, [],
     "hyperparameter 'normalize' is one of rl_zoo3's that food-fetch train does not implement"),
    (None, ["--eval-freq", "4", "--hyperparams", "eval_freq=8"],
     "--eval-freq 4 and --hyperparams eval_freq=8 disagree: give --eval-freq only"),
    (None, ["--eval-episodes", "0"], "--eval-episodes: must be >= 1"),
    (None, ["--save-freq", "often"], "--save-freq: not a number: 'often'"),
])
def test_run_settings_mistakes_are_one_line_and_write_nothing(
        block: dict[str, object] | None, argv: list[str], fragment: str, tmp_path: Path,
        capsys: pytest.CaptureFixture[str]) -> None:
    log = tmp_path / "run"
    hp = tmp_path / "hp.yml"
    if block is not None:
        hp.write_text(yaml.safe_dump({ENV: block}))
        argv = [*argv, "--hyperparams-file", str(hp)]
    code, _, err = run_cli(["train", "--env", ENV, "--timesteps", "2", "--no-progress",
                            "--log-dir", str(log), *argv], capsys)
    assert_one_line_error(code, err)
    assert fragment.replace("{hp}", str(hp)) in err
    assert not log.exists()
