"""``food-fetch train``: help, one-line errors, a short run with checkpoints, config.yml,
resuming, and the saved model as an agent of ``food-fetch evaluate``."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
import yaml

from agents.cli import main
from agents.train import load_hyperparams
from tests.cli_helpers import assert_one_line_error, run_cli

pytest.importorskip("stable_baselines3")

FAST = ["--hyperparams", "n_steps=8", "batch_size=8", "n_epochs=2", "eval_freq=8",
        "n_eval_episodes=1", "checkpoint_freq=8", "env_kwargs={estimator: none}"]


def test_help_lists_the_options(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exc:
        main(["train", "--help"])
    assert exc.value.code == 0
    out = capsys.readouterr().out
    for opt in ("--algo", "--env", "--timesteps", "--seed", "--log-dir", "--resume",
                "--hyperparams", "config.yml"):
        assert opt in out


@pytest.mark.parametrize("argv, fragment", [
    (["--env", "FoodFetch-Nope-v0"], "unknown environment id 'FoodFetch-Nope-v0'"),
    (["--algo", "dqn"], "invalid choice: 'dqn'"),
    (["--timesteps", "many"], "--timesteps: not a number: 'many'"),
    (["--timesteps", "0"], "--timesteps: must be >= 1"),
    (["--resume", "nope/ckpt.zip"], "checkpoint not found: 'nope/ckpt.zip'"),
    (["--hyperparams", "learning_rate"], "override must be key=value"),
    (["--hyperparams-file", "missing.yml"], "cannot read hyperparameter file"),
    (["--log-dir", "/proc/version/x"], "--log-dir: cannot write to"),
])
def test_mistakes_are_one_line_and_exit_2(argv: list[str], fragment: str,
                                         capsys: pytest.CaptureFixture[str]) -> None:
    code, _, err = run_cli(["train", *argv], capsys)
    assert_one_line_error(code, err)
    assert fragment in err


def test_shipped_hyperparameters_cover_every_id() -> None:
    for algo in ("ppo", "sac"):
        for env_id in ("FoodFetch-Block-v0", "FoodFetch-Row-v0", "FoodFetch-TwoRows-v0",
                       "FoodFetch-Diced-v0"):
            hp = load_hyperparams(algo, env_id)
            assert hp["policy"] == "MlpPolicy" and hp["n_timesteps"] > 0
    assert load_hyperparams("ppo", "FoodFetch-Block-v0", overrides={"n_steps": 8})["n_steps"] == 8


def test_short_run_checkpoints_resumes_and_evaluates(tmp_path: Path,
                                                    capsys: pytest.CaptureFixture[str]) -> None:
    log = tmp_path / "run"
    code, out, err = run_cli(["train", "--algo", "ppo", "--timesteps", "16", "--seed", "1",
                           "--log-dir", str(log), "--no-progress", *FAST], capsys)
    assert code == 0, err
    for name in ("model.zip", "config.yml", "progress.csv", "eval/evaluations.npz",
                 "checkpoints/rl_model_16_steps.zip"):
        assert (log / name).exists(), name
    cfg = yaml.safe_load((log / "config.yml").read_text())
    assert cfg["algo"] == "ppo" and cfg["env"] == "FoodFetch-Block-v0" and cfg["seed"] == 1
    assert cfg["timesteps"] == 16 and cfg["finished_steps"] == 16
    assert cfg["hyperparams"]["n_steps"] == 8 and "stable_baselines3" in cfg["versions"]
    assert "evaluate --agent" in out

    # Resume from the checkpoint up to 24 steps in all.
    log2 = tmp_path / "resumed"
    code, _, err = run_cli(["train", "--algo", "ppo", "--timesteps", "24", "--seed", "1",
                         "--log-dir", str(log2), "--no-progress", "--no-eval",
                         "--resume", str(log / "checkpoints/rl_model_16_steps.zip"), *FAST],
                        capsys)
    assert code == 0, err
    cfg2 = yaml.safe_load((log2 / "config.yml").read_text())
    assert cfg2["resumed_at_step"] == 16 and cfg2["finished_steps"] == 24

    js = tmp_path / "e.json"
    code, _, err = run_cli(["evaluate", "--agent", str(log2 / "model.zip"), "--episodes", "1",
                         "--json", str(js), "--quiet"], capsys)
    assert code == 0, err
    d = json.loads(js.read_text())
    assert d["agents"][str(log2 / "model.zip")]["episodes"] == 1


def test_a_file_that_is_not_a_model_is_refused(tmp_path: Path,
                                               capsys: pytest.CaptureFixture[str]) -> None:
    bad = tmp_path / "model.zip"
    bad.write_bytes(b"PK\x05\x06" + b"\0" * 18)  # an empty zip archive
    code, _, err = run_cli(["evaluate", "--agent", str(bad), "--episodes", "1"], capsys)
    assert_one_line_error(code, err)


@pytest.mark.slow
def test_sac_a_few_hundred_steps(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code, _, err = run_cli(["train", "--algo", "sac", "--timesteps", "300", "--log-dir",
                         str(tmp_path), "--no-progress", "--hyperparams", "learning_starts=50",
                         "eval_freq=150", "n_eval_episodes=5", "checkpoint_freq=150"], capsys)
    assert code == 0, err
    assert (tmp_path / "checkpoints/rl_model_replay_buffer_300_steps.pkl").exists()
