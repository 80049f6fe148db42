"""``evaluate --ray``, the estimator validation harness's ``--ray`` and ``train --backend
rllib`` on a local Ray instance started by the test (2 CPUs, no network): the same numbers as
``--workers 1``, a stop that keeps what finished, one line for a bad address, an RLlib run
whose exported policy evaluates and matches the module it came from.  Skipped where the
``ray`` extra is not installed; the RLlib tests where the ``rllib`` extra is not.

Cheap settings: FoodFetch-Block-v0 with the oracle estimator (no probe simulations) for the
stop and equality runs; the search agent on one scene to check its simulations spread over
Ray give the serial search's choice.
"""

from __future__ import annotations

import importlib.util
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest

pytest.importorskip("ray")
# The RLlib tests need the rllib extra (dm_tree is installed by it alone); .ci/run runs them
# in a venv of their own, as RLlib pins gymnasium.
needs_rllib = pytest.mark.skipif(
    importlib.util.find_spec("tree") is None or importlib.util.find_spec("lz4") is None,
    reason="needs the rllib extra: pip install -e '.[rllib]'")

ROOT = Path(__file__).resolve().parent.parent
TIMEOUT = 300  # a Ray start is ~5-10 s, a worker's imports a few more: beyond this, a hang
ENV = {**os.environ, "PYTHONPATH": str(ROOT), "RAY_AUTH_MODE": "disabled",
       "RAY_worker_niceness": "0", "RAY_USAGE_STATS_ENABLED": "0"}


def _cli(*args: str) -> list[str]:
    return [sys.executable, "-m", "agents.cli", *args]


def _run(argv: list[str], cwd: Path) -> tuple[int, str, str]:
    proc = subprocess.run(argv, cwd=cwd, capture_output=True, text=True, env=ENV,
                          timeout=TIMEOUT)
    return proc.returncode, proc.stdout, proc.stderr


def _start(argv: list[str], cwd: Path) -> subprocess.Popen[str]:
    return subprocess.Popen(argv, cwd=cwd, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, env=ENV, start_new_session=True)


def _wait_for_lines(path: Path, n: int, proc: subprocess.Popen[str]) -> None:
    """Until ``path`` has ``n`` lines (or the run ended, or TIMEOUT passed)."""
    deadline = time.monotonic() + TIMEOUT
    while time.monotonic() < deadline and proc.poll() is None:
        if path.exists() and len(path.read_text().splitlines()) >= n:
            return
        time.sleep(0.2)


def _stderr_once_ended(proc: subprocess.Popen[str], timeout: float, what: str) -> str:
    try:
        return proc.communicate(timeout=timeout)[1]
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        pytest.fail(f"still running {timeout:.0f} s after {what} (a hang)")


def _same(rec: dict[str, Any]) -> dict[str, Any]:
    return {k: v for k, v in rec.items() if k != "wall_s"}


def _numbers(payload: dict[str, Any]) -> dict[str, Any]:
    return {a: {k: v for k, v in s.items() if not k.startswith("wall_s")}
            for a, s in payload["agents"].items()}


def test_ray_gives_the_numbers_of_one_worker_search_included(tmp_path: Path) -> None:
    common = ["evaluate", "--env", "FoodFetch-Block-v0", "--agent", "study", "--agent",
              "random", "--agent", "search", "--search-episodes", "1", "--episodes", "3",
              "--seed", "11", "--quiet", "--json-episodes"]
    code, out, err = _run(_cli(*common, "--json", "one.json"), tmp_path)
    assert code == 0, err
    code, out, err = _run(_cli(*common, "--ray", "--workers", "2", "--json", "ray.json"),
                          tmp_path)
    assert code == 0, err
    assert "Ray at local" in out and "Traceback" not in err
    one, ray = (json.loads((tmp_path / f).read_text()) for f in ("one.json", "ray.json"))
    assert ray["ray"] == "local"
    assert _numbers(ray) == _numbers(one)
    assert [_same(r) for r in ray["episodes_detail"]] == [
        _same(r) for r in one["episodes_detail"]]


@pytest.mark.parametrize(("extra", "message"), [
    (["--ray", "no-port"], "bad Ray address 'no-port'"),
    (["--ray", "host:99999"], "bad Ray address 'host:99999'"),
    (["--ray", "127.0.0.1:1"], "no Ray cluster answers at '127.0.0.1:1'"),
    (["--ray-batch", "2"], "--ray-batch needs --ray"),
])
def test_bad_ray_settings_are_one_line_before_any_episode(tmp_path: Path, extra: list[str],
                                                          message: str) -> None:
    code, _out, err = _run(_cli("evaluate", "--episodes", "2", "--json", "x.json", *extra),
                          tmp_path)
    assert code == 2, err
    lines = [ln for ln in err.splitlines() if "Warning" not in ln and "deprecation" not in ln]
    assert len(lines) == 1 and message in lines[0] and "Traceback" not in err, err
    assert not (tmp_path / "x.json").exists()


def test_sigterm_on_ray_keeps_what_finished(tmp_path: Path) -> None:
    argv = _cli("evaluate", "--env", "FoodFetch-Block-v0", "--env-kwargs", "estimator=oracle",
                "--agent", "study", "--episodes", "60", "--seed", "3", "--ray", "--workers",
                "2", "--ray-batch", "1", "--quiet", "--json", "part.json", "--json-episodes")
    proc = _start(argv, tmp_path)
    log = tmp_path / "part.episodes.jsonl"
    _wait_for_lines(log, 4, proc)  # the header and 3 episodes
    proc.send_signal(signal.SIGTERM)
    err = _stderr_once_ended(proc, 60, "SIGTERM")
    assert proc.returncode == 128 + signal.SIGTERM, err
    assert "stopped by SIGTERM" in err and "Traceback" not in err, err
    part = json.loads((tmp_path / "part.json").read_text())
    kept = [json.loads(x) for x in log.read_text().splitlines()[1:]]
    assert part["interrupted"] and 3 <= part["episodes_finished"] < 60
    assert part["episodes_finished"] == len(kept)


def _harness(*args: str) -> list[str]:
    return [sys.executable, str(ROOT / "benchmarks" / "validate_estimators.py"), "--set",
            "tuning", "--preset", "env", "--no-calibration", *args]


def _without_timing(rec: dict[str, Any]) -> dict[str, Any]:
    return {k: v for k, v in rec.items() if not k.startswith(("wall_", "cpu_"))}


def test_validation_harness_on_ray_gives_the_records_of_one_worker(tmp_path: Path) -> None:
    """The estimator validation harness's foods as Ray tasks: every record the one a single
    process writes, but for its timings."""
    code, _, err = _run(_harness("--n", "3", "--out", "one"), tmp_path)
    assert code == 0, err
    code, _, err = _run(_harness("--n", "3", "--out", "ray", "--ray", "--workers", "2"),
                        tmp_path)
    assert code == 0 and "Traceback" not in err, err
    one, ray = (json.loads((tmp_path / d / "tuning_env_uncal_noise0.json").read_text())
                for d in ("one", "ray"))
    assert len(one["records"]) == 3
    assert [_without_timing(r) for r in ray["records"]] == [
        _without_timing(r) for r in one["records"]]


@pytest.mark.parametrize(("extra", "message"), [
    (["--ray", "127.0.0.1:1"], "no Ray cluster answers at '127.0.0.1:1'"),
    (["--ray", "no-port"], "bad Ray address 'no-port'"),
    (["--ray-batch", "2"], "--ray-batch needs --ray"),
])
def test_bad_ray_settings_stop_the_harness_before_any_food(tmp_path: Path, extra: list[str],
                                                           message: str) -> None:
    code, _, err = _run(_harness("--n", "2", "--out", "out", *extra), tmp_path)
    assert code == 2 and message in err.splitlines()[-1] and "Traceback" not in err, err
    assert not (tmp_path / "out").exists()


def test_sigterm_stops_the_harness_on_ray_and_keeps_what_finished(tmp_path: Path) -> None:
    proc = _start(_harness("--n", "40", "--out", "out", "--ray", "--workers", "2",
                           "--ray-batch", "1"), tmp_path)
    log = tmp_path / "out" / "tuning_env_uncal_noise0.jsonl"
    _wait_for_lines(log, 3, proc)
    proc.send_signal(signal.SIGTERM)
    err = _stderr_once_ended(proc, 60, "SIGTERM")
    assert proc.returncode == 128 + signal.SIGTERM, err
    assert "interrupted (SIGTERM)" in err and "Traceback" not in err, err
    kept = log.read_text().splitlines()
    part = json.loads((tmp_path / "out" / "tuning_env_uncal_noise0.json").read_text())
    assert 3 <= len(kept) < 40 and len(part["records"]) == len(kept)
    assert part["meta"]["stopped"] == "interrupted (SIGTERM)"


def test_a_task_that_raises_on_ray_ends_the_run_keeping_what_finished(tmp_path: Path) -> None:
    """run_on_ray with a function of the caller's: the tasks before the one that raises
    come back, then TaskFailed names that task and its error in one line."""
    script = """
from agents.ray_runner import TaskFailed, run_on_ray

def half(x):
    if x == 3:
        raise ValueError(f"no half of {x}")
    return x / 2

got = {}
try:
    run_on_ray([2, 4, 3, 6], got.__setitem__, "local", 1, batch=1, run=half)
except TaskFailed as exc:
    print("failed", exc.task, exc.error, sorted(got.items()))
"""
    code, out, err = _run([sys.executable, "-c", script], tmp_path)
    assert code == 0, err
    assert "failed 3 ValueError: no half of 3 [(0, 1.0), (1, 2.0)]" in out, (out, err)


def test_evaluate_reports_a_failed_ray_task_as_its_episode(monkeypatch: pytest.MonkeyPatch
                                                           ) -> None:
    """A task that raised on a Ray worker ends the evaluation like one that raised here:
    EvaluationInterrupted naming the agent, episode and seed, exit code 1."""
    from agents import ray_runner
    from agents.evaluate import EvaluationInterrupted, Task, run_tasks

    tasks = [Task("study", "FoodFetch-Block-v0", i, 100 + i) for i in range(3)]

    def fake(tasks_: list[Task], collect: Any, *_args: Any, **_kw: Any) -> None:
        collect(0, {"episode": 0})
        raise ray_runner.TaskFailed(tasks_[1], "RuntimeError: boom")

    monkeypatch.setattr(ray_runner, "run_on_ray", fake)
    with pytest.raises(EvaluationInterrupted) as info:
        run_tasks(tasks, ray_address="local")
    assert info.value.code == 1 and info.value.results == [{"episode": 0}]
    assert info.value.reason == "'study' episode 1 (seed 101) failed: RuntimeError: boom"


def test_batches_cover_every_task_once() -> None:
    from agents.ray_runner import batches

    for n, batch, cpus in [(1, None, 2), (7, None, 2), (200, None, 2), (200, None, 64),
                           (10, 3, 2)]:
        groups = batches(n, batch, cpus)
        assert [i for g in groups for i in g] == list(range(n))
        assert max(len(g) for g in groups) <= (batch or 8)


TINY = """\
{env}:
  n_timesteps: 32
  training: {{lr: 0.0003, train_batch_size_per_learner: 16, minibatch_size: 8, num_epochs: 2}}
  model: {{fcnet_hiddens: [16, 16]}}
  env_runners: {{rollout_fragment_length: auto}}
"""


@needs_rllib
def test_rllib_ppo_trains_checkpoints_and_its_policy_evaluates(tmp_path: Path) -> None:
    env_id = "FoodFetch-Block-v0"
    (tmp_path / "tiny.yml").write_text(TINY.format(env=env_id))
    code, _out, err = _run(_cli("train", "--backend", "rllib", "--algo", "ppo", "--env", env_id,
                               "--hyperparams-file", "tiny.yml", "--log-dir", "run",
                               "--no-progress", "--quasi-static"), tmp_path)
    assert code == 0, err
    run = tmp_path / "run"
    import yaml

    # --quasi-static: the env kwargs the env runners made the env with (fetch_env.quasi_static)
    assert yaml.safe_load((run / "config.yml").read_text())["env_kwargs"] == {
        "fetch_hold_scale": 5.0, "fetch_clamp_speed": 0.1}
    rows = (run / "progress.csv").read_text().splitlines()
    assert rows[0].startswith("iteration,steps") and int(rows[-1].split(",")[1]) >= 32
    ckpts = sorted(p.name for p in (run / "checkpoints").iterdir())
    assert ckpts and all(not c.endswith(".tmp") for c in ckpts)
    meta = json.loads((run / "policy.json").read_text())
    assert meta["algo"] == "ppo" and meta["obs_dim"] == 15 and meta["action_dim"] == 3
    # The exported network is the trained module's: rebuilt from the checkpoint by RLlib
    # itself, its mean action matches the numpy policy's on random observations.
    from ray.rllib.core.rl_module.rl_module import RLModule

    from agents.rllib_policy import RLlibPolicyAgent

    last = run / "checkpoints" / ckpts[-1]
    module = RLModule.from_checkpoint(str(last / "learner_group" / "learner" / "rl_module"
                                          / "default_policy"))
    import torch

    obs = np.random.default_rng(0).uniform(-2, 2, (8, 15)).astype(np.float32)
    with torch.no_grad():
        mean = module.forward_inference({"obs": torch.as_tensor(obs)})[
            "action_dist_inputs"].numpy()[:, :3]
    agent = RLlibPolicyAgent(run / "policy.npz")
    np.testing.assert_allclose([agent.act(o) for o in obs], np.clip(mean, -1, 1),
                               rtol=1e-4, atol=1e-5)
    code, _out, err = _run(_cli("evaluate", "--agent", str(run / "policy.npz"), "--env",
                               env_id, "--episodes", "2", "--quiet", "--json", "e.json"),
                          tmp_path)
    assert code == 0, err
    summary = json.loads((tmp_path / "e.json").read_text())["agents"]
    assert summary[str(run / "policy.npz")]["episodes"] == 2
    # A second run on the folder is refused without --overwrite, the first run's files intact.
    before = (run / "policy.npz").read_bytes()
    code, _out, err = _run(_cli("train", "--backend", "rllib", "--env", env_id,
                               "--hyperparams-file", "tiny.yml", "--log-dir", "run"), tmp_path)
    assert code == 2 and "holds an earlier run" in err, err
    assert (run / "policy.npz").read_bytes() == before


@needs_rllib
@pytest.mark.parametrize(("extra", "message"), [
    (["--resume", "x.zip"], "--resume is not taken with --backend rllib"),
    (["--env-runners", "2"], "--env-runners and --ray need --backend rllib"),
    (["--backend", "rllib", "--ray", "nohost"], "bad Ray address 'nohost'"),
    (["--backend", "rllib", "--hyperparams-file", "/nonexistent.yml"], "cannot read"),
])
def test_bad_rllib_requests_are_one_line(tmp_path: Path, extra: list[str],
                                         message: str) -> None:
    argv = ["train", *extra]
    if "--resume" in extra:
        argv = ["train", "--backend", "rllib", *extra]
    code, _out, err = _run(_cli(*argv, "--log-dir", "r"), tmp_path)
    assert code == 2, err
    assert message in err and "Traceback" not in err, err
    assert not (tmp_path / "r" / "policy.npz").exists()


@needs_rllib
def test_sigterm_stops_rllib_training_with_a_checkpoint_and_the_policy(tmp_path: Path) -> None:
    env_id = "FoodFetch-Block-v0"
    (tmp_path / "tiny.yml").write_text(TINY.format(env=env_id))
    argv = _cli("train", "--backend", "rllib", "--env", env_id, "--hyperparams-file",
                "tiny.yml", "--timesteps", "100000", "--log-dir", "run", "--no-progress")
    proc = _start(argv, tmp_path)
    progress = tmp_path / "run" / "progress.csv"
    _wait_for_lines(progress, 2, proc)  # the header and one iteration
    proc.send_signal(signal.SIGTERM)
    err = _stderr_once_ended(proc, 120, "SIGTERM")
    assert proc.returncode == 128 + signal.SIGTERM, err
    lines = [ln for ln in err.splitlines() if ln.startswith("food-fetch train:")]
    assert len(lines) == 1 and "stopped by SIGTERM" in lines[0] and "Traceback" not in err
    steps = int(progress.read_text().splitlines()[-1].split(",")[1])
    assert (tmp_path / "run" / "checkpoints" / f"rllib_{steps}_steps").is_dir()
    assert (tmp_path / "run" / "policy.npz").is_file()


def _free_port() -> int:
    import socket

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


@pytest.mark.slow
def test_a_cluster_that_goes_away_ends_the_run_with_one_line_and_keeps_what_finished(
        tmp_path: Path) -> None:
    port = _free_port()
    # A head of its own, in its own process group (--block keeps its processes children of
    # it): killing that group is the cluster going away, and touches no other Ray instance.
    head = subprocess.Popen([sys.executable, "-m", "ray.scripts.scripts", "start", "--head",
                             "--block", "--port", str(port), "--num-cpus", "2",
                             "--include-dashboard=false", "--disable-usage-stats"], env=ENV,
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                            start_new_session=True)
    try:
        from agents.ray_runner import why_unreachable

        deadline = time.monotonic() + TIMEOUT
        while why_unreachable(f"127.0.0.1:{port}") is not None and time.monotonic() < deadline:
            time.sleep(0.5)
        time.sleep(3)  # the head's raylet registers after its GCS answers
        argv = _cli("evaluate", "--env", "FoodFetch-Block-v0", "--env-kwargs",
                    "estimator=oracle", "--agent", "study", "--episodes", "200", "--ray",
                    f"127.0.0.1:{port}", "--ray-batch", "1", "--quiet", "--json", "c.json")
        proc = _start(argv, tmp_path)
        log = tmp_path / "c.episodes.jsonl"
        _wait_for_lines(log, 4, proc)
    finally:
        os.killpg(head.pid, signal.SIGKILL)
        head.wait(30)
    err = _stderr_once_ended(proc, 120, "the cluster stopped")
    assert proc.returncode == 1, err
    ours = [ln for ln in err.splitlines() if ln.startswith("food-fetch evaluate:")]
    assert len(ours) == 1 and "Traceback" not in err, err
    assert "Ray" in ours[0] and "episodes finished" in ours[0]
    kept = log.read_text().splitlines()[1:]
    part = json.loads((tmp_path / "c.json").read_text())
    assert part["interrupted"] and part["episodes_finished"] == len(kept) >= 3


def test_the_docs_scaling_table_is_the_committed_benchmark() -> None:
    sys.path.insert(0, str(ROOT / "benchmarks"))
    import scaling

    data = json.loads((ROOT / "docs/data/scaling.json").read_text())
    page = (ROOT / "docs/scaling.md").read_text()
    table = page.split(scaling.BEGIN)[1].split(scaling.END)[0].strip()
    assert table == scaling.render(data)
    # 2 workers, and Ray with 2 CPUs and batched tasks, run faster than 1 (on 2 cores).
    assert data["workers"]["2"]["episodes_per_s"] > 1.2 * data["workers"]["1"]["episodes_per_s"]
    assert (data["ray"]["2"]["batch_4"]["episodes_per_s"]
            > 1.2 * data["ray"]["1"]["batch_4"]["episodes_per_s"])
