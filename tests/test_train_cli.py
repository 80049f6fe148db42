"""``food-fetch train``: help, one-line errors, a short run with checkpoints, config.yml,
resuming, and the saved model as an agent of ``food-fetch evaluate``."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest
import yaml

from agents.cli import main
from agents.cli.common import DEFAULT_ENV
from agents.train import load_hyperparams, parse_override
from tests.cli_helpers import assert_help_lists, assert_one_line_error, run_cli

pytest.importorskip("stable_baselines3")

FAST = ["--hyperparams", "n_steps=8", "batch_size=8", "n_epochs=2", "eval_freq=8",
        "n_eval_episodes=1", "checkpoint_freq=8", "env_kwargs={estimator: none}"]


def test_help_lists_the_options(capsys: pytest.CaptureFixture[str]) -> None:
    assert_help_lists("train", ("--algo", "--env", "--timesteps", "--seed", "--log-dir",
                                "--resume", "--hyperparams", "config.yml"), capsys)


@pytest.mark.parametrize("argv, fragment", [
    (["--env", "FoodFetch-Nope-v0"], "unknown environment id 'FoodFetch-Nope-v0'"),
    (["--algo", "dqn"], "invalid choice: 'dqn'"),
    (["--timesteps", "many"], "--timesteps: not a number: 'many'"),
    (["--timesteps", "0"], "--timesteps: must be >= 1"),
    (["--seed", "-1"], "--seed: -1 is not in [0, 4294967295]"),
    (["--seed", "4294967296"], "--seed: 4294967296 is not in [0, 4294967295]"),
    (["--seed", "1.5"], "--seed: not an integer: '1.5'"),
    (["--resume", "nope/ckpt.zip"], "checkpoint not found: 'nope/ckpt.zip'"),
    (["--hyperparams", "learning_rate"], "override must be key=value"),
    (["--hyperparams", "=3"], "override must be key=value"),
    (["--hyperparams-file", "missing.yml"], "cannot read hyperparameter file"),
    (["--log-dir", "/proc/version/x"], "--log-dir: cannot write to"),
    (["--log-dir", ""], "--log-dir: not a directory name: ''"),
])
def test_mistakes_are_one_line_and_exit_2(argv: list[str], fragment: str, tmp_path: Path,
                                         capsys: pytest.CaptureFixture[str]) -> None:
    log = tmp_path / "run"
    code, _, err = run_cli(["train", "--log-dir", str(log), *argv], capsys)
    assert_one_line_error(code, err)
    assert fragment in err
    assert not log.exists()


BLOCK_NOT_A_MAPPING = f"{DEFAULT_ENV}: 5\n"  # the id train runs without --env


@pytest.mark.parametrize("hyperparams, fragment", [
    (["n_envs=abc"], "bad hyperparameter n_envs='abc': must be an integer in [1, 64]"),
    (["n_envs=0"], "bad hyperparameter n_envs=0: must be an integer in [1, 64]"),
    (["n_envs=2.0"], "bad hyperparameter n_envs=2.0: must be an integer"),
    (["eval_freq=abc"], "bad hyperparameter eval_freq='abc': must be an integer >= 0"),
    (["n_timesteps=-5"], "bad hyperparameter n_timesteps=-5: must be an integer >= 1"),
    (["n_eval_episodes=0"], "bad hyperparameter n_eval_episodes=0: must be an integer >= 1"),
    (["checkpoint_freq=yes"], "bad hyperparameter checkpoint_freq=True: must be an integer"),
    (["batch_size=0"], "bad hyperparameter batch_size=0: must be an integer >= 2"),
    (["learning_rate=abc"], "bad hyperparameter learning_rate='abc': must be a number > 0"),
    (["n_steps=1"], "bad hyperparameter n_steps=1: n_steps x n_envs must be >= 2"),
    ([f"n_envs={10**400}"], "bad hyperparameter n_envs=1000000000"),  # no OverflowError
    (["use_sde=1"], "bad hyperparameter use_sde=1: must be true or false"),
    (["use_sde=true", "sde_sample_freq=abc"],  # SB3 itself fails only in learn()
     "bad hyperparameter sde_sample_freq='abc': must be an integer >= -1"),
    (["stats_window_size=0"], "bad hyperparameter stats_window_size=0: must be an integer >= 1"),
    (["rollout_buffer_class=foo"], "bad hyperparameter rollout_buffer_class='foo': must be null"),
    (["policy=Foo"], "bad hyperparameter policy='Foo': choose from MlpPolicy"),
    (["seed=3"], "bad hyperparameter seed=3: food-fetch train sets it (--seed)"),
    (["bogus_key=1"], "unknown ppo hyperparameter 'bogus_key'"),
    (["env_kwargs=5"], "bad hyperparameter env_kwargs=5: must be a mapping"),
    # raised by the env and by SB3 while they are built: still one line naming the key
    (["env_kwargs={bogus: 1}"], "bad hyperparameter env_kwargs={'bogus': 1}: "
     "FoodFetchEnv.__init__() got an unexpected keyword argument 'bogus'"),
    (["env_kwargs={fetch_weight: -1}"], "env_kwargs={'fetch_weight': -1}: fetch_weight must"),
    (["policy_kwargs={net_arch: abc}"], "bad ppo hyperparameters policy_kwargs={'net_arch': "),
    ([], f"the {DEFAULT_ENV} entry of"),  # with --hyperparams-file BLOCK_NOT_A_MAPPING
])
def test_bad_hyperparameters_are_one_line_and_write_nothing(
        hyperparams: list[str], fragment: str, tmp_path: Path,
        capsys: pytest.CaptureFixture[str]) -> None:
    log = tmp_path / "run"
    argv = ["train", "--timesteps", "2", "--no-eval", "--no-progress", "--log-dir", str(log)]
    if hyperparams:
        argv += ["--hyperparams", *hyperparams]
    else:
        (tmp_path / "hp.yml").write_text(BLOCK_NOT_A_MAPPING)
        argv += ["--hyperparams-file", str(tmp_path / "hp.yml")]
    code, _, err = run_cli(argv, capsys)
    assert_one_line_error(code, err)
    assert fragment in err
    assert not log.exists()  # checked (and built) before the log dir is created


@pytest.mark.parametrize("hyperparams, fragment", [
    (["ent_coef=-1"], "bad hyperparameter ent_coef=-1: must be a number >= 0"),
    (["ent_coef=abc"], "bad sac hyperparameters ent_coef='abc': could not convert string"),
    (["action_noise=foo"], "bad hyperparameter action_noise='foo': must be null"),
    (["train_freq=[1, hour]"], "bad hyperparameter train_freq=[1, 'hour']: must be an integer"),
])
def test_bad_sac_hyperparameters_are_one_line(hyperparams: list[str], fragment: str,
                                              tmp_path: Path,
                                              capsys: pytest.CaptureFixture[str]) -> None:
    log = tmp_path / "run"
    code, _, err = run_cli(["train", "--algo", "sac", "--timesteps", "2", "--no-eval",
                            "--no-progress", "--log-dir", str(log), "--hyperparams",
                            *hyperparams], capsys)
    assert_one_line_error(code, err)
    assert fragment in err
    assert not log.exists()


def test_overrides_read_floats_as_users_write_them() -> None:
    # PyYAML alone reads 1e-3 as the string '1e-3', which SB3 then rejects
    assert parse_override("learning_rate=1e-3") == ("learning_rate", 0.001)
    assert parse_override("net_arch=[32, 32]") == ("net_arch", [32, 32])
    assert parse_override("ent_coef=auto") == ("ent_coef", "auto")
    assert parse_override("learning_rate=3E4") == ("learning_rate", 30000.0)
    assert parse_override("learning_rate=1.5e-4") == ("learning_rate", 0.00015)
    assert parse_override("n_steps=64") == ("n_steps", 64)
    assert parse_override("target_kl=null") == ("target_kl", None)


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
    assert cfg["algo"] == "ppo" and cfg["env"] == DEFAULT_ENV and cfg["seed"] == 1
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


# A finished run whose n_steps (16) a resume changes; checkpoints at 8 and 16 steps.
RUN16 = ["--hyperparams", "n_steps=16", "batch_size=16", "n_epochs=2", "eval_freq=8",
         "n_eval_episodes=1", "checkpoint_freq=8", "env_kwargs={estimator: none}"]


@pytest.fixture(scope="module")
def finished_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A finished 16-step PPO run, trained once for the module; tests work on copies."""
    log = tmp_path_factory.mktemp("finished") / "run"
    assert main(["train", "--timesteps", "16", "--seed", "1", "--log-dir", str(log),
                 "--no-progress", *RUN16]) == 0
    return log


def _copy(run: Path, tmp_path: Path) -> Path:
    return Path(shutil.copytree(run, tmp_path / "run"))


def _snapshot(root: Path) -> dict[str, bytes]:
    return {str(p.relative_to(root)): p.read_bytes() for p in sorted(root.rglob("*"))
            if p.is_file()}


def _csv_rows(path: Path) -> list[dict[str, str]]:
    import csv

    with open(path, newline="") as fh:
        rows = list(csv.reader(fh))
    assert all(len(r) == len(rows[0]) for r in rows), "ragged CSV"
    return [dict(zip(rows[0], r, strict=True)) for r in rows[1:]]


@pytest.mark.parametrize("argv, fragment", [
    (["--hyperparams", "bogus_key=1"], "unknown ppo hyperparameter 'bogus_key'"),
    # --overwrite deletes the earlier run only once the new one is built: not here
    (["--overwrite", "--hyperparams", "env_kwargs={bogus: 1}"], "env_kwargs={'bogus': 1}"),
    (["--overwrite", "--hyperparams", "policy_kwargs={net_arch: abc}"],
     "bad ppo hyperparameters policy_kwargs="),
    (["--hyperparams", "batch_size=0"], "bad hyperparameter batch_size=0"),
    ([], "already holds a run (model.zip): --overwrite replaces it"),
    (["--overwrite", "--resume", "{run}/model.zip", "--timesteps", "24"],
     "give one of them"),
    (["--algo", "sac", "--resume", "{run}/model.zip"],
     "model.zip' is a ppo model, not sac: use --algo ppo"),
    (["--resume", "{tmp}/notzip.zip"],
     "notzip.zip' is not a valid Stable-Baselines3 model (not a zip file)"),
    (["--resume", "{run}/model.zip", "--timesteps", "16"],
     "--timesteps 16 is not past the checkpoint's 16 steps"),
    (["--resume", "{run}/checkpoints/rl_model_8_steps.zip", "--timesteps", "24"],
     "already holds 16 steps, past the checkpoint's 8"),
    (["--resume", "{run}/model.zip", "--timesteps", "24",
      "--hyperparams", "policy_kwargs={net_arch: [8]}"], "cannot change policy_kwargs on --resume"),
    (["--resume", "{run}/model.zip", "--timesteps", "24", "--hyperparams", "n_eval_episodes=3"],
     "n_eval_episodes=3: the earlier evaluations"),
])
def test_a_failed_call_leaves_an_earlier_run_as_it_was(
        argv: list[str], fragment: str, finished_run: Path, tmp_path: Path,
        capsys: pytest.CaptureFixture[str]) -> None:
    run = _copy(finished_run, tmp_path)
    (tmp_path / "notzip.zip").write_text("not a zip\n")
    before = _snapshot(run)
    argv = [a.replace("{run}", str(run)).replace("{tmp}", str(tmp_path)) for a in argv]
    code, _, err = run_cli(["train", "--timesteps", "2", "--no-progress", "--log-dir", str(run),
                            *argv], capsys)
    assert_one_line_error(code, err)
    assert fragment in err
    assert _snapshot(run) == before  # not one byte of progress.csv, monitor/ etc. changed


def test_resume_applies_new_n_steps_and_appends_to_its_log_dir(
        finished_run: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    run = _copy(finished_run, tmp_path)
    before = _snapshot(run)
    old_progress = _csv_rows(run / "progress.csv")
    code, _, err = run_cli(["train", "--resume", str(run / "checkpoints/rl_model_16_steps.zip"),
                            "--timesteps", "24", "--seed", "1", "--log-dir", str(run),
                            "--no-progress", "--hyperparams", "n_steps=8", "batch_size=8",
                            "n_epochs=2", "eval_freq=8", "n_eval_episodes=1",
                            "env_kwargs={estimator: none}"], capsys)
    assert code == 0, err
    cfg = yaml.safe_load((run / "config.yml").read_text())
    # The checkpoint's n_steps=16 would collect a whole 16-step rollout: 32 steps, not 24.
    assert cfg["resumed_at_step"] == 16 and cfg["finished_steps"] == 24
    assert cfg["hyperparams"]["n_steps"] == 8 and cfg["hyperparams"]["batch_size"] == 8
    assert cfg["previous_runs"][0]["finished_steps"] == 16
    assert cfg["previous_runs"][0]["hyperparams"]["n_steps"] == 16
    # monitor: the 16 earlier episodes kept byte for byte, 8 appended (one step each)
    monitor = (run / "monitor/0.monitor.csv").read_bytes()
    assert monitor.startswith(before["monitor/0.monitor.csv"])
    assert monitor.count(b"\n") == before["monitor/0.monitor.csv"].count(b"\n") + 8
    # progress.csv: the earlier rows first, then the resumed run's, up to step 24
    steps = [r["time/total_timesteps"] for r in _csv_rows(run / "progress.csv")]
    assert steps[:len(old_progress)] == [r["time/total_timesteps"] for r in old_progress]
    assert len(steps) > len(old_progress) and steps[-1] == "24"
    with np.load(run / "eval/evaluations.npz") as ev:
        assert ev["timesteps"].tolist() == [8, 16, 24]
    assert (run / "checkpoints/rl_model_8_steps.zip").read_bytes() == \
        before["checkpoints/rl_model_8_steps.zip"]


def test_a_ppo_checkpoint_is_an_agent_of_evaluate(finished_run: Path, tmp_path: Path,
                                                  capsys: pytest.CaptureFixture[str]) -> None:
    # No config.yml next to a checkpoint: the algorithm comes from the model itself.
    ckpt = finished_run / "checkpoints/rl_model_8_steps.zip"
    code, _, err = run_cli(["evaluate", "--agent", str(ckpt), "--episodes", "1", "--json",
                            str(tmp_path / "e.json"), "--quiet"], capsys)
    assert code == 0, err


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
    # the replay buffer as npz, read back without pickle (agents.train_safety)
    assert (tmp_path / "checkpoints/rl_model_replay_buffer_300_steps.npz").exists()


def test_resume_without_env_continues_on_the_checkpoints_env(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    log = tmp_path / "v1"
    code, _, err = run_cli(["train", "--algo", "ppo", "--env", "FoodFetch-Block-v1",
                            "--timesteps", "8", "--log-dir", str(log), "--no-progress",
                            "--no-eval", *FAST], capsys)
    assert code == 0, err
    log2 = tmp_path / "resumed"
    code, out, err = run_cli(["train", "--timesteps", "16", "--log-dir", str(log2),
                              "--no-progress", "--no-eval", "--resume",
                              str(log / "model.zip"), *FAST], capsys)
    assert code == 0, err
    assert yaml.safe_load((log2 / "config.yml").read_text())["env"] == "FoodFetch-Block-v1"
    assert "--env FoodFetch-Block-v1" in out


def test_quasi_static_trains_on_the_ids_setting(tmp_path: Path,
                                                capsys: pytest.CaptureFixture[str]) -> None:
    """--quasi-static puts the id's validated setting (fetch_env.quasi_static) under the
    hyperparameters' env_kwargs, whose own values win, and config.yml records them."""
    from fetch_env.quasi_static import quasi_static_kwargs

    log = tmp_path / "qs"
    code, _, err = run_cli(["train", "--algo", "ppo", "--timesteps", "8", "--seed", "1",
                            "--log-dir", str(log), "--no-progress", "--no-eval",
                            "--quasi-static", "--hyperparams", "n_steps=8", "batch_size=8",
                            "n_epochs=1", "env_kwargs={fetch_clamp_speed: 0.1}"], capsys)
    assert code == 0, err
    cfg = yaml.safe_load((log / "config.yml").read_text())
    assert quasi_static_kwargs(DEFAULT_ENV)["fetch_clamp_speed"] != 0.1
    assert cfg["hyperparams"]["env_kwargs"] == {"fetch_hold_scale": 5.0,
                                                "fetch_clamp_speed": 0.1}
