"""Faults injected into ``food-fetch train`` and untrusted files handed to it and to
``evaluate``: a second run on a locked folder, a new run on a folder holding a model, SIGTERM
mid-training then ``--resume``, a lock left by a dead run, and model files and replay buffers
crafted so that unpickling them would create a marker file.

Cheap settings: FoodFetch-Block-v0 with the oracle estimator (no probe simulations, ~0.3 s a
step), PPO rollouts of 8 steps, budgets of tens of steps.  The training that is stopped runs
in a subprocess (the real command, signals and all); the rest runs in this process.
"""

from __future__ import annotations

import base64
import hashlib
import io
import json
import os
import pickle
import shutil
import signal
import subprocess
import sys
import time
import zipfile
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml

from agents.cli import main
from tests.cli_helpers import assert_one_line_error, run_cli

pytest.importorskip("stable_baselines3")

ROOT = Path(__file__).resolve().parent.parent
ORACLE = "env_kwargs={estimator: oracle}"
PPO_FAST = ["--hyperparams", "n_steps=8", "batch_size=8", "n_epochs=1", ORACLE]
TIMEOUT = 180  # no run here comes near it: beyond it, a hang


def _checksums(root: Path) -> dict[str, str]:
    return {str(p.relative_to(root)): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(root.rglob("*")) if p.is_file()}


def _monitor_rows(log: Path) -> int:
    path = log / "monitor" / "0.monitor.csv"
    if not path.is_file():
        return 0
    return max(0, len(path.read_text().splitlines()) - 2)  # a "#{...}" line, the header


def _start(log: Path, *argv: str) -> subprocess.Popen[str]:
    env = {**os.environ, "PYTHONWARNINGS": "ignore"}
    return subprocess.Popen([sys.executable, "-m", "agents.cli", "train", "--log-dir", str(log),
                             "--no-progress", *argv], cwd=ROOT, env=env, text=True,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE)


def _wait_for_rows(proc: subprocess.Popen[str], log: Path, rows: int) -> None:
    deadline = time.monotonic() + TIMEOUT
    while _monitor_rows(log) < rows:
        if proc.poll() is not None:
            pytest.fail(f"training ended early: {proc.communicate()[1][-2000:]}")
        if time.monotonic() > deadline:
            proc.kill()
            pytest.fail("training wrote no episodes in time")
        time.sleep(0.2)


def _stop_with_sigterm(proc: subprocess.Popen[str]) -> tuple[int, str]:
    proc.send_signal(signal.SIGTERM)
    try:
        _, err = proc.communicate(timeout=TIMEOUT)
    except subprocess.TimeoutExpired:
        proc.kill()
        pytest.fail("SIGTERM did not stop training")
    return proc.returncode, err


@pytest.fixture(scope="module")
def interrupted(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    """A PPO run in a subprocess: paused (SIGSTOP) mid-training while a second run tries its
    folder, then resumed (SIGCONT) and stopped with SIGTERM."""
    log = tmp_path_factory.mktemp("interrupted") / "run"
    proc = _start(log, "--timesteps", "400", "--seed", "3", "--no-eval", "--save-freq", "0",
                  *PPO_FAST)
    _wait_for_rows(proc, log, 3)
    proc.send_signal(signal.SIGSTOP)
    try:
        before = _checksums(log)
        second = {}
        for extra in ([], ["--overwrite"]):
            code = main(["train", "--log-dir", str(log), "--timesteps", "8", "--no-progress",
                         *extra, *PPO_FAST])
            second[" ".join(extra) or "plain"] = code
        after = _checksums(log)
    finally:
        proc.send_signal(signal.SIGCONT)
    code, err = _stop_with_sigterm(proc)
    return {"log": log, "pid": proc.pid, "before": before, "after": after, "second": second,
            "code": code, "err": err}


def test_a_second_run_on_a_locked_folder_is_refused_and_changes_nothing(
        interrupted: dict[str, Any], capsys: pytest.CaptureFixture[str]) -> None:
    assert interrupted["second"] == {"plain": 2, "--overwrite": 2}
    assert "train.lock" in interrupted["before"] and "model.zip" not in interrupted["before"]
    assert interrupted["after"] == interrupted["before"]  # every byte, the lock file's too


def test_the_refusal_is_one_line_naming_the_first_run_s_process(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """The refusal's text, against a lock held here by a live process (this test's)."""
    from agents.train_safety import RunLock

    log = tmp_path / "run"
    lock = RunLock.acquire(log, ["food-fetch", "train"])
    try:
        code, _, err = run_cli(["train", "--log-dir", str(log), "--timesteps", "8",
                                "--no-progress", *PPO_FAST], capsys)
    finally:
        lock.release()
    assert_one_line_error(code, err)
    assert f"is in use by another food-fetch train run (process {os.getpid()} on " in err
    assert not (log / "train.lock").exists()  # released


def test_sigterm_saves_a_checkpoint_and_says_how_to_resume(
        interrupted: dict[str, Any]) -> None:
    log, err = interrupted["log"], interrupted["err"]
    assert interrupted["code"] == 128 + signal.SIGTERM, err
    lines = [ln for ln in err.splitlines() if ln.startswith("food-fetch train:")]
    assert len(lines) == 1 and "Traceback" not in err, err
    cfg = yaml.safe_load((log / "config.yml").read_text())
    steps = cfg["stopped"]["at_step"]
    ckpt = log / "checkpoints" / f"rl_model_{steps}_steps.zip"
    assert cfg["stopped"]["by"] == "SIGTERM" and cfg["finished_steps"] == steps
    assert 3 <= steps < 400 and ckpt.is_file() and (log / "model.zip").is_file()
    assert f"stopped by SIGTERM at step {steps} of 400; saved {ckpt}" in lines[0]
    assert f"--resume {ckpt} --log-dir {log} --timesteps 400" in lines[0]
    assert not (log / "train.lock").exists()
    assert not list(log.rglob("*.part*"))  # no temporary file left behind


def test_resume_continues_the_stopped_run(interrupted: dict[str, Any], tmp_path: Path,
                                          capsys: pytest.CaptureFixture[str]) -> None:
    log = Path(shutil.copytree(interrupted["log"], tmp_path / "run"))
    steps = yaml.safe_load((log / "config.yml").read_text())["stopped"]["at_step"]
    rows = _monitor_rows(log)
    code, _, err = run_cli(["train", "--log-dir", str(log), "--no-progress", "--no-eval",
                            "--save-freq", "0", "--seed", "3", "--timesteps", str(steps + 8),
                            "--resume", str(log / f"checkpoints/rl_model_{steps}_steps.zip"),
                            *PPO_FAST], capsys)
    assert code == 0, err
    cfg = yaml.safe_load((log / "config.yml").read_text())
    assert cfg["resumed_at_step"] == steps and cfg["finished_steps"] >= steps + 8
    assert cfg["previous_runs"][0]["stopped"]["at_step"] == steps
    assert _monitor_rows(log) == rows + cfg["finished_steps"] - steps  # one row a step


# --------------------------------------------------------------------- an existing model
@pytest.fixture(scope="module")
def finished(tmp_path_factory: pytest.TempPathFactory) -> Path:
    log = tmp_path_factory.mktemp("finished") / "run"
    assert main(["train", "--log-dir", str(log), "--timesteps", "8", "--no-progress",
                 "--no-eval", "--save-freq", "8", *PPO_FAST]) == 0
    return log


@pytest.mark.parametrize("what", ["model.zip", "config.yml", "checkpoint"])
def test_an_existing_run_is_not_replaced_without_overwrite(
        what: str, finished: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    log = Path(shutil.copytree(finished, tmp_path / "run"))
    keep = {"model.zip": ["model.zip"], "config.yml": ["config.yml"],
            "checkpoint": ["checkpoints/rl_model_8_steps.zip"]}[what]
    for p in [p for p in log.rglob("*") if p.is_file()]:
        if str(p.relative_to(log)) not in keep:
            p.unlink()  # the folder holds this one piece of a run
    before = _checksums(log)
    code, _, err = run_cli(["train", "--log-dir", str(log), "--timesteps", "8",
                            "--no-progress", *PPO_FAST], capsys)
    assert_one_line_error(code, err)
    assert "already holds a run" in err and "--overwrite replaces it" in err
    assert _checksums(log) == before


def test_overwrite_replaces_the_earlier_run_whole(finished: Path, tmp_path: Path,
                                                  capsys: pytest.CaptureFixture[str]) -> None:
    log = Path(shutil.copytree(finished, tmp_path / "run"))
    old = (log / "model.zip").read_bytes()
    code, _, err = run_cli(["train", "--log-dir", str(log), "--timesteps", "8", "--seed", "5",
                            "--no-progress", "--no-eval", "--save-freq", "0", "--overwrite",
                            *PPO_FAST], capsys)
    assert code == 0, err
    assert (log / "model.zip").read_bytes() != old
    assert not (log / "checkpoints/rl_model_8_steps.zip").exists()  # the earlier run's
    assert yaml.safe_load((log / "config.yml").read_text())["seed"] == 5


def test_a_lock_left_by_a_dead_run_is_taken_over_with_a_note(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()  # a process id that no longer runs
    log = tmp_path / "run"
    log.mkdir()
    (log / "train.lock").write_text(json.dumps({"pid": dead.pid, "host": "somewhere",
                                                "started": "earlier"}))
    code, _, err = run_cli(["train", "--log-dir", str(log), "--timesteps", "8",
                            "--no-progress", "--no-eval", "--save-freq", "0", *PPO_FAST], capsys)
    assert code == 0, err
    assert f"taking over the lock of process {dead.pid} on somewhere" in err
    assert not (log / "train.lock").exists()


# ------------------------------------------------------------------- untrusted model files
class _Marker:
    """Unpickling this creates ``path`` (pickle calls ``open(path, "w")``)."""

    def __init__(self, path: Path) -> None:
        self.path = str(path)

    def __reduce__(self) -> tuple[Any, tuple[str, str]]:
        return (open, (self.path, "w"))


def _evil(marker: Path) -> str:
    return base64.b64encode(pickle.dumps(_Marker(marker))).decode()


def _craft(model: Path, out: Path, marker: Path, extra: dict[str, Any] | None = None) -> Path:
    """``model`` with every cloudpickled entry of its data replaced by one that creates
    ``marker`` when unpickled (the text SB3 writes beside each pickle kept), plus ``extra``
    entries."""
    with zipfile.ZipFile(model) as zf:
        members = {name: zf.read(name) for name in zf.namelist()}
    data = json.loads(members["data"])
    crafted = 0
    for value in data.values():
        if isinstance(value, dict) and ":serialized:" in value:
            value[":serialized:"] = _evil(marker)
            crafted += 1
    assert crafted >= 8  # policy class, spaces, schedules, rollout state...
    data.update(extra or {})
    members["data"] = json.dumps(data).encode()
    with zipfile.ZipFile(out, "w") as zf:
        for name, payload in members.items():
            zf.writestr(name, payload)
    return out


@pytest.fixture(scope="module")
def models(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """A PPO and a SAC model that have trained a few steps (so that every kind of pickled
    entry is in their data)."""
    import gymnasium as gym
    from stable_baselines3 import PPO, SAC

    import fetch_env  # noqa: F401 (registers the ids)

    root = tmp_path_factory.mktemp("models")
    env = gym.make("FoodFetch-Block-v0", estimator="oracle")
    ppo = PPO("MlpPolicy", env, n_steps=8, batch_size=8, n_epochs=1, device="cpu", seed=0)
    ppo.learn(8)
    ppo.save(root / "ppo.zip")
    sac = SAC("MlpPolicy", env, learning_starts=2, batch_size=4, device="cpu", seed=0)
    sac.learn(4)
    sac.save(root / "sac.zip")
    env.close()
    return {"ppo": root / "ppo.zip", "sac": root / "sac.zip"}


def test_the_crafted_file_does_run_code_under_plain_sb3(models: dict[str, Path],
                                                       tmp_path: Path) -> None:
    """The check that the tests below can fail: SB3's own load unpickles, and the marker
    appears."""
    from stable_baselines3 import PPO

    marker = tmp_path / "marker"
    crafted = _craft(models["ppo"], tmp_path / "crafted.zip", marker)
    try:
        PPO.load(crafted, device="cpu")
    except Exception:  # the "policy class" it unpickled is a file object
        pass
    assert marker.exists()


def test_evaluate_loads_a_crafted_model_without_running_its_code(
        models: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    marker = tmp_path / "marker"
    for algo in ("ppo", "sac"):
        crafted = _craft(models[algo], tmp_path / f"{algo}.zip", marker)
        code, _, err = run_cli(["evaluate", "--agent", str(crafted), "--episodes", "1",
                                "--env-kwargs", "estimator=oracle", "--json",
                                str(tmp_path / f"{algo}.json"), "--quiet"], capsys)
        assert code == 0, err
        assert not marker.exists(), algo


def test_the_agent_acts_as_the_model_does(models: dict[str, Path]) -> None:
    """Rebuilding the pickled entries changes nothing the policy does."""
    from stable_baselines3 import PPO, SAC

    from agents.sb3_agent import SB3Agent

    obs = np.random.default_rng(0).uniform(-1, 1, 15).astype(np.float32)
    for algo, cls in (("ppo", PPO), ("sac", SAC)):
        plain = cls.load(models[algo], device="cpu").predict(obs, deterministic=True)[0]
        assert np.array_equal(SB3Agent(models[algo]).act(obs), plain), algo


@pytest.mark.parametrize("extra, fragment", [
    ({"evil_entry": {":type:": "<class 'object'>"}}, "pickled 'evil_entry'"),
    ({"policy_kwargs": {":type:": "<class 'dict'>"}}, "pickled 'policy_kwargs'"),
])
def test_a_pickled_entry_that_cannot_be_rebuilt_refuses_the_file(
        extra: dict[str, Any], fragment: str, models: dict[str, Path], tmp_path: Path,
        capsys: pytest.CaptureFixture[str]) -> None:
    marker = tmp_path / "marker"
    for value in extra.values():
        value[":serialized:"] = _evil(marker)
    crafted = _craft(models["ppo"], tmp_path / "crafted.zip", marker, extra)
    code, _, err = run_cli(["evaluate", "--agent", str(crafted), "--episodes", "1"], capsys)
    assert_one_line_error(code, err)
    assert fragment in err and "does not unpickle" in err
    log = tmp_path / "run"
    code, _, err = run_cli(["train", "--resume", str(crafted), "--timesteps", "16",
                            "--log-dir", str(log), "--no-progress", *PPO_FAST], capsys)
    assert_one_line_error(code, err)
    assert fragment in err
    assert not marker.exists() and not log.exists()


def test_train_resumes_from_a_crafted_checkpoint_without_running_its_code(
        models: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    marker = tmp_path / "marker"
    crafted = _craft(models["ppo"], tmp_path / "crafted.zip", marker)
    log = tmp_path / "run"
    code, _, err = run_cli(["train", "--resume", str(crafted), "--timesteps", "16",
                            "--log-dir", str(log), "--no-progress", "--no-eval",
                            "--save-freq", "0", *PPO_FAST], capsys)
    assert code == 0, err
    assert not marker.exists()
    assert yaml.safe_load((log / "config.yml").read_text())["finished_steps"] >= 16


def test_a_pickled_replay_buffer_is_refused_unless_trusted(
        models: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    marker = tmp_path / "marker"
    ckpts = tmp_path / "checkpoints"
    ckpts.mkdir()
    shutil.copy(models["sac"], ckpts / "rl_model_4_steps.zip")
    (ckpts / "rl_model_replay_buffer_4_steps.pkl").write_bytes(pickle.dumps(_Marker(marker)))
    log = tmp_path / "run"
    code, _, err = run_cli(["train", "--resume", str(ckpts / "rl_model_4_steps.zip"),
                            "--timesteps", "8", "--log-dir", str(log), "--no-progress",
                            "--hyperparams", ORACLE], capsys)
    assert_one_line_error(code, err)
    assert "is a pickle, which can run code" in err and "--trust-replay-buffer" in err
    assert not marker.exists() and not log.exists()


# ------------------------------------------------------------------------------------ SAC
def test_sac_stopped_by_sigterm_resumes_with_its_replay_buffer(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    log = tmp_path / "run"
    sac = ["--algo", "sac", "--no-eval", "--save-freq", "0", "--hyperparams",
           "learning_starts=4", "batch_size=8", ORACLE]
    proc = _start(log, "--timesteps", "400", *sac)
    _wait_for_rows(proc, log, 6)
    code, err = _stop_with_sigterm(proc)
    assert code == 128 + signal.SIGTERM, err
    steps = yaml.safe_load((log / "config.yml").read_text())["stopped"]["at_step"]
    buf = log / "checkpoints" / f"rl_model_replay_buffer_{steps}_steps.npz"
    with np.load(buf, allow_pickle=False) as npz:
        assert json.loads(str(npz["meta"]))["pos"] == steps  # every counted step kept
        assert npz["observations"].shape == (steps, 1, 15)
    code, _, err = run_cli(["train", "--log-dir", str(log), "--no-progress",
                            "--timesteps", str(steps + 4), "--resume",
                            str(log / f"checkpoints/rl_model_{steps}_steps.zip"), *sac], capsys)
    assert code == 0, err
    cfg = yaml.safe_load((log / "config.yml").read_text())
    assert cfg["replay_buffer_from"] == str(buf) and cfg["finished_steps"] == steps + 4


def test_sighup_and_sigint_stop_as_sigterm_does_and_a_second_signal_interrupts() -> None:
    from agents.train_safety import StopSignals

    for sig in (signal.SIGHUP, signal.SIGINT, signal.SIGTERM):
        with StopSignals() as stop:
            os.kill(os.getpid(), sig)
            time.sleep(0.01)  # Python runs the handler between bytecodes
            assert stop.signum == sig and stop.name == signal.Signals(sig).name
            with pytest.raises(KeyboardInterrupt):
                os.kill(os.getpid(), signal.SIGTERM)
                time.sleep(0.01)
    assert signal.getsignal(signal.SIGTERM) == signal.SIG_DFL  # restored


def test_a_replay_buffer_round_trips_through_npz(tmp_path: Path) -> None:
    """save_replay_buffer / load_replay_buffer give back the same arrays and position."""
    from gymnasium.spaces import Box
    from stable_baselines3.common.buffers import ReplayBuffer

    from agents.train_safety import load_replay_buffer, save_replay_buffer

    obs, act = Box(-1, 1, (15,), np.float32), Box(-1, 1, (3,), np.float32)
    src, dst = ReplayBuffer(10, obs, act, device="cpu"), ReplayBuffer(10, obs, act, device="cpu")
    rng = np.random.default_rng(0)
    for _ in range(13):  # past the end: the buffer wraps and is full
        src.add(rng.random((1, 15)), rng.random((1, 15)), rng.random((1, 3)), rng.random(1),
                np.zeros(1), [{}])
    save_replay_buffer(src, tmp_path / "b.npz")
    load_replay_buffer(dst, tmp_path / "b.npz")
    assert (dst.pos, dst.full) == (src.pos, src.full) == (3, True)
    for key in ("observations", "next_observations", "actions", "rewards", "dones"):
        assert np.array_equal(getattr(dst, key), getattr(src, key)), key
    with io.BytesIO() as raw:  # and nothing in the file needs pickle
        raw.write((tmp_path / "b.npz").read_bytes())
        raw.seek(0)
        with np.load(raw, allow_pickle=False) as npz:
            assert "meta" in npz.files
