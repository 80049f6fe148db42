"""Faults injected into a running ``food-fetch evaluate`` (the real command, in a subprocess):
SIGTERM, SIGHUP, a worker killed with SIGKILL once and twice, the resource tracker killed,
the output folder removed, a write to a full device.  Each ends with every finished episode
kept, one line saying what happened, a conventional exit code, and no traceback, hang or
leaked-semaphore warning; a stopped run resumed from its episode log gives the numbers of
an uninterrupted one.

Cheap settings: FoodFetch-Block-v0 with the oracle estimator (no probe simulations), the
random and study agents, tens of episodes (~0.2 s each).  A ``reference`` run with one
worker gives the numbers every other run is held to (episode i of an agent is the scene of
``reset(seed=SEED + i)`` in any run, so any subset of episodes can be compared).
"""

from __future__ import annotations

import json
import os
import re
import shutil
import signal
import stat
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import pytest

from agents.atomic import atomic_path, write_atomic

ROOT = Path(__file__).resolve().parent.parent
SEED = 7
EPISODES = 30  # per agent: 60 tasks, ~12 s with one worker
AGENTS = ("random", "study")
TIMEOUT = 120  # no run here takes a third of it: beyond it, a hang


def _argv(*extra: str) -> list[str]:
    agents = [x for a in AGENTS for x in ("--agent", a)]
    return [sys.executable, "-m", "agents.cli", "evaluate", "--env", "FoodFetch-Block-v0",
            "--env-kwargs", "estimator=oracle", *agents, "--seed", str(SEED), "--quiet",
            *extra]


def _default_signals() -> None:
    """In the child before exec: the stop signals at their defaults and not blocked, as under
    a scheduler (a background shell job would start with SIGINT ignored)."""
    for sig in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP):
        signal.signal(sig, signal.SIG_DFL)
    signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT, signal.SIGTERM, signal.SIGHUP})


def _start(argv: list[str], cwd: Path) -> subprocess.Popen[str]:
    return subprocess.Popen(argv, cwd=cwd, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, env={**os.environ, "PYTHONPATH": str(ROOT)},
                            preexec_fn=_default_signals, start_new_session=True)


def _finish(proc: subprocess.Popen[str], timeout: float) -> tuple[str, str]:
    """stdout and stderr once ``proc`` ends; a run still going after ``timeout`` is a hang:
    its whole process group is killed and the test fails."""
    try:
        return proc.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        out, err = proc.communicate()
        pytest.fail(f"still running after {timeout:.0f} s (a hang)\n{out}\n{err}")


def _run(argv: list[str], cwd: Path) -> tuple[int, str, str, float]:
    t0 = time.perf_counter()
    proc = _start(argv, cwd)
    out, err = _finish(proc, TIMEOUT)
    return proc.returncode, out, err, time.perf_counter() - t0


WARNING = re.compile(r"^\S+:\d+: \w*Warning: ")


def _lines(err: str) -> list[str]:
    """stderr without Python warnings (``file:line: XWarning: text`` and the source line
    after it): gymnasium's deprecation of -v0 ids, the env's clipping warnings."""
    lines, out = err.strip().splitlines(), []
    for i, line in enumerate(lines):
        if WARNING.match(line) or (i and WARNING.match(lines[i - 1])
                                   and line.startswith("  ")):
            continue
        out.append(line)
    return out


def _one_line(err: str, fragment: str) -> str:
    """The command's only line on stderr, which holds ``fragment``; no traceback, no
    warning of leaked semaphores."""
    lines = _lines(err)
    assert "Traceback" not in err and "leaked" not in err, err
    assert len(lines) == 1 and fragment in lines[0], err
    return lines[0]


def _logged(path: Path) -> list[dict[str, Any]]:
    """The episode log's records (its header dropped; a line still being written, read
    while the run goes on, left out: the final counts are checked against the JSON)."""
    out = []
    for line in (path.read_text().splitlines() if path.exists() else [])[1:]:
        try:
            out.append(json.loads(line))
        except json.JSONDecodeError:
            continue
    return out


def _wait_for(log: Path, n: int, proc: subprocess.Popen[str]) -> None:
    """Until the log holds ``n`` records (the run still going)."""
    deadline = time.monotonic() + TIMEOUT
    while len(_logged(log)) < n:
        assert proc.poll() is None, "the run ended before the fault was injected"
        assert time.monotonic() < deadline, f"fewer than {n} episodes in {TIMEOUT} s"
        time.sleep(0.02)


def _children(pid: int, marker: bytes) -> list[int]:
    """The child processes of ``pid`` whose command line holds ``marker``."""
    out = []
    for task in Path(f"/proc/{pid}/task").iterdir():
        for child in (task / "children").read_text().split():
            try:
                cmdline = Path(f"/proc/{child}/cmdline").read_bytes()
            except OSError:
                continue
            if marker in cmdline:
                out.append(int(child))
    return out


def _workers(pid: int) -> list[int]:
    """The pool's worker processes of ``pid`` (spawned; not the resource tracker)."""
    return _children(pid, b"spawn_main")


def _key(r: dict[str, Any]) -> tuple[str, int]:
    return r["agent"], r["episode"]


def _same(r: dict[str, Any]) -> dict[str, Any]:
    return {k: v for k, v in r.items() if k != "wall_s"}  # all but the wall time


def _numbers(d: dict[str, Any]) -> dict[str, Any]:
    return {a: {k: v for k, v in s.items() if k != "wall_s_mean"} for a, s in d["agents"].items()}


def _as_reference(records: list[dict[str, Any]], reference: dict[str, Any]) -> None:
    """Every record equals the reference run's record of its (agent, episode)."""
    ref = {_key(r): _same(r) for r in reference["episodes_detail"]}
    assert records and [_same(r) for r in records] == [ref[_key(r)] for r in records]


@pytest.fixture(scope="module")
def reference(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    """The uninterrupted run with one worker: its JSON (every episode) and its wall time."""
    folder = tmp_path_factory.mktemp("reference")
    code, _out, err, wall = _run(_argv("--episodes", str(EPISODES), "--json", "ref.json",
                                       "--json-episodes"), folder)
    assert code == 0, err
    d = json.loads((folder / "ref.json").read_text())
    assert len(d["episodes_detail"]) == len(AGENTS) * EPISODES
    return {**d, "wall": wall}


# ------------------------------------------------------------------------------ signals
@pytest.mark.slow
def test_sigterm_at_half_keeps_every_finished_episode_and_resume_matches(
        tmp_path: Path, reference: dict[str, Any]) -> None:
    proc = _start(_argv("--episodes", str(EPISODES), "--json", "part.json", "--json-episodes"),
                  tmp_path)
    log = tmp_path / "part.episodes.jsonl"
    _wait_for(log, EPISODES, proc)  # half of the 2 x EPISODES tasks
    t0 = time.perf_counter()
    proc.send_signal(signal.SIGTERM)
    out, err = _finish(proc, TIMEOUT)
    stop_s = time.perf_counter() - t0
    assert proc.returncode == 128 + signal.SIGTERM, err
    line = _one_line(err, "stopped by SIGTERM")
    assert "--resume part.episodes.jsonl" in line and "INTERRUPTED" in out
    assert stop_s < 10, f"{stop_s:.1f} s from SIGTERM to exit"
    part = json.loads((tmp_path / "part.json").read_text())
    kept = _logged(log)
    assert part["interrupted"] and part["episodes_finished"] == len(kept)
    assert EPISODES <= len(kept) < 2 * EPISODES
    assert sorted(map(_key, kept)) == sorted(map(_key, part["episodes_detail"]))
    _as_reference(kept, reference)

    code, out, err, _ = _run(_argv("--episodes", str(EPISODES), "--json", "res.json",
                                   "--json-episodes", "--resume", "part.episodes.jsonl"),
                             tmp_path)
    assert code == 0, err
    resumed = json.loads((tmp_path / "res.json").read_text())
    assert resumed["episodes_from_log"] == len(kept)  # only the rest ran
    assert _numbers(resumed) == _numbers(reference)
    assert [_same(r) for r in resumed["episodes_detail"]] == [
        _same(r) for r in reference["episodes_detail"]]
    assert sorted(map(_key, _logged(log))) == sorted(map(_key, reference["episodes_detail"]))


@pytest.mark.slow
def test_sighup_with_two_workers_stops_them_and_keeps_what_finished(
        tmp_path: Path, reference: dict[str, Any]) -> None:
    proc = _start(_argv("--episodes", str(EPISODES), "--workers", "2", "--json", "h.json",
                        "--json-episodes"), tmp_path)
    _wait_for(tmp_path / "h.episodes.jsonl", 4, proc)
    workers = _workers(proc.pid)
    assert len(workers) == 2
    proc.send_signal(signal.SIGHUP)
    _out, err = _finish(proc, TIMEOUT)
    assert proc.returncode == 128 + signal.SIGHUP, err
    _one_line(err, "stopped by SIGHUP")
    d = json.loads((tmp_path / "h.json").read_text())
    kept = _logged(tmp_path / "h.episodes.jsonl")
    assert d["interrupted"] and d["episodes_finished"] == len(kept) >= 4
    _as_reference(kept, reference)
    for pid in workers:  # gone, or a zombie no one reaps in a container: none runs on
        state = Path(f"/proc/{pid}/stat")
        assert not state.exists() or state.read_text().split(") ")[1][0] in "ZX"


# ------------------------------------------------------------------------------ lost workers
@pytest.mark.slow
def test_a_killed_worker_costs_at_most_twice_the_normal_time(
        tmp_path: Path, reference: dict[str, Any]) -> None:
    """SIGKILL (the out-of-memory killer) of one of two workers: within twice the time of
    the same run without a fault, all episodes with the numbers of ``--workers 1``, or a
    stop with one line having kept what finished."""
    argv = _argv("--episodes", str(EPISODES), "--workers", "2", "--json-episodes")
    code, _out, err, normal = _run([*argv, "--json", "normal.json"], tmp_path)
    assert code == 0, err
    _as_reference(json.loads((tmp_path / "normal.json").read_text())["episodes_detail"],
                  reference)
    t0 = time.perf_counter()
    proc = _start([*argv, "--json", "k.json"], tmp_path)
    _wait_for(tmp_path / "k.episodes.jsonl", EPISODES // 3, proc)
    os.kill(_workers(proc.pid)[0], signal.SIGKILL)
    _out, err = _finish(proc, max(1.0, 2 * normal - (time.perf_counter() - t0)))
    d = json.loads((tmp_path / "k.json").read_text())
    if proc.returncode == 0:  # the lost tasks ran again on a fresh pool
        _one_line(err, "a worker process died")
        assert _numbers(d) == _numbers(reference)
        assert [_same(r) for r in d["episodes_detail"]] == [
            _same(r) for r in reference["episodes_detail"]]
    else:
        assert proc.returncode == 1 and "Traceback" not in err and "leaked" not in err, err
        assert d["episodes_finished"] == len(_logged(tmp_path / "k.episodes.jsonl"))
        _as_reference(d["episodes_detail"], reference)


@pytest.mark.slow
def test_a_worker_lost_twice_stops_with_one_line(tmp_path: Path,
                                                 reference: dict[str, Any]) -> None:
    proc = _start(_argv("--episodes", str(EPISODES), "--workers", "2", "--json", "t.json",
                        "--json-episodes"), tmp_path)
    log = tmp_path / "t.episodes.jsonl"
    _wait_for(log, 4, proc)
    first = _workers(proc.pid)
    os.kill(first[0], signal.SIGKILL)
    deadline = time.monotonic() + TIMEOUT
    while not (fresh := [p for p in _workers(proc.pid) if p not in first]):
        assert proc.poll() is None and time.monotonic() < deadline, "no fresh pool started"
        time.sleep(0.05)
    os.kill(fresh[0], signal.SIGKILL)
    _out, err = _finish(proc, TIMEOUT)
    assert proc.returncode == 1, err
    lines = _lines(err)
    assert "Traceback" not in err and "leaked" not in err, err
    assert len(lines) == 2 and "run again on a fresh pool" in lines[0]  # the first loss
    assert "died again" in lines[1] and "--resume t.episodes.jsonl" in lines[1]
    d = json.loads(Path(tmp_path / "t.json").read_text())
    kept = _logged(log)
    assert d["interrupted"] and d["episodes_finished"] == len(kept) >= 4
    assert sorted(map(_key, kept)) == sorted(map(_key, d["episodes_detail"]))
    _as_reference(kept, reference)


@pytest.mark.slow
def test_a_killed_resource_tracker_leaves_no_traceback(tmp_path: Path,
                                                       reference: dict[str, Any]) -> None:
    """multiprocessing's resource tracker killed mid-run: its relaunch at exit printed a
    KeyError traceback per semaphore (exit code 0); now nothing is said and nothing leaks."""
    proc = _start(_argv("--episodes", str(EPISODES // 2), "--workers", "2", "--json", "r.json",
                        "--json-episodes"), tmp_path)
    _wait_for(tmp_path / "r.episodes.jsonl", 4, proc)
    (tracker,) = _children(proc.pid, b"resource_tracker")
    os.kill(tracker, signal.SIGKILL)
    _out, err = _finish(proc, TIMEOUT)
    assert proc.returncode == 0, err
    assert _lines(err) == [] and "Traceback" not in err and "resource_tracker" not in err, err
    d = json.loads((tmp_path / "r.json").read_text())
    assert d["episodes_finished"] == len(AGENTS) * (EPISODES // 2)
    _as_reference(d["episodes_detail"], reference)


# ------------------------------------------------------------------------------ failed writes
def _fallback(line: str) -> Path:
    """The fallback file named at the end of the one-line error."""
    return Path(line.rsplit("are in ", 1)[1].strip("'"))


def _table_printed(out: str, episodes: int) -> None:
    rows = [line.split() for line in out.splitlines()]
    assert {r[0] for r in rows if r[1:2] == [str(episodes)]} >= set(AGENTS), out


def _holds_every_episode(d: dict[str, Any], episodes: int) -> None:
    from agents.episode_log import json_safe, restore_record
    from agents.evaluate import summarize

    records = d["episodes_detail"]
    assert sorted(map(_key, records)) == sorted((a, i) for a in AGENTS for i in range(episodes))
    assert all(r["seed"] == SEED + r["episode"] for r in records)
    again = summarize([restore_record(r) for r in records], list(AGENTS))
    assert d["agents"] == json.loads(json.dumps(json_safe(again)))


def test_output_folder_removed_mid_run(tmp_path: Path) -> None:
    """--json, --csv and the episode log in a folder removed while episodes still run: the
    table, every episode in the named fallback file (in the current folder), exit code 1."""
    out_dir, cwd = tmp_path / "out", tmp_path / "cwd"
    out_dir.mkdir()
    cwd.mkdir()
    episodes = 8
    proc = _start(_argv("--episodes", str(episodes), "--json", str(out_dir / "x.json"),
                        "--csv", str(out_dir / "x.csv")), cwd)
    _wait_for(out_dir / "x.episodes.jsonl", 2, proc)
    shutil.rmtree(out_dir)
    out, err = _finish(proc, TIMEOUT)
    assert proc.returncode == 1, err
    assert "Traceback" not in err and "leaked" not in err, err
    notice, line = _lines(err)  # said when the log went, and at the end
    assert f"the episode log '{out_dir / 'x.episodes.jsonl'}' stopped taking records" in notice
    assert f"cannot write '{out_dir / 'x.json'}' (No such file or directory)" in line
    assert str(out_dir / "x.csv") in line and str(out_dir / "x.episodes.jsonl") in line
    _table_printed(out, episodes)
    fallback = _fallback(line)
    assert fallback.parent == cwd and not out_dir.exists()
    _holds_every_episode(json.loads(fallback.read_text()), episodes)


@pytest.mark.skipif(not Path("/dev/full").exists(), reason="no /dev/full")
def test_a_write_to_a_full_device(tmp_path: Path) -> None:
    """--json /dev/full: ENOSPC at the end; the table, the CSV, every episode in the named
    fallback file, exit code 1, and /dev/full still the device it was."""
    code, out, err, _ = _run(_argv("--episodes", "2", "--json", "/dev/full", "--csv", "x.csv"),
                             tmp_path)
    assert code == 1, err
    line = _one_line(err, "cannot write '/dev/full' (No space left on device)")
    _table_printed(out, 2)
    _holds_every_episode(json.loads(_fallback(line).read_text()), 2)
    assert len((tmp_path / "x.csv").read_text().splitlines()) == 1 + 2 * len(AGENTS)
    assert stat.S_ISCHR(os.stat("/dev/full").st_mode)


@pytest.mark.skipif(not Path("/dev/full").exists(), reason="no /dev/full")
def test_an_episode_log_on_a_full_device_is_refused_before_any_episode(tmp_path: Path) -> None:
    code, out, err, _ = _run(_argv("--episodes", "2", "--episodes-log", "/dev/full"), tmp_path)
    assert code == 2 and out == "", err
    _one_line(err, "cannot write the episode log '/dev/full': No space left on device")
    assert stat.S_ISCHR(os.stat("/dev/full").st_mode)


# ------------------------------------------------------------------------------ small n
def test_two_episodes_print_no_interval(tmp_path: Path) -> None:
    """``evaluate --episodes 2``: each episode's value and "n too small", no interval at
    all (a t interval gave "time/fetch 1.69 ± 5.77" here, far below zero)."""
    code, out, err, _ = _run(_argv("--episodes", "2", "--json", "s.json"), tmp_path)
    assert code == 0, err
    rows = [line for line in out.splitlines() if line.split()[:1] in ([a] for a in AGENTS)]
    assert len(rows) == len(AGENTS)
    assert not any("±" in row or "[" in row for row in rows), out
    assert "n too small (< 5 episodes)" in out
    d = json.loads((tmp_path / "s.json").read_text())
    for s in d["agents"].values():
        assert s["n_too_small"]
        for key in ("reward", "fetch_rate", "max_log_strain", "time_per_fetch", "success_rate"):
            assert s[f"{key}_ci95"] == [None, None] and len(s[f"{key}_values"]) == 2


# ------------------------------------------------------------------------------ atomic files
def test_a_failed_write_leaves_the_old_file_and_no_temporary(tmp_path: Path) -> None:
    target = tmp_path / "r.json"
    target.write_text("old")
    with pytest.raises(RuntimeError), atomic_path(target) as tmp:
        tmp.write_text("half")
        raise RuntimeError("stopped mid-write")
    assert target.read_text() == "old" and [p.name for p in tmp_path.iterdir()] == ["r.json"]
    write_atomic(target, "new")
    assert target.read_text() == "new" and [p.name for p in tmp_path.iterdir()] == ["r.json"]


def test_a_link_stays_a_link_and_a_fifo_is_written_not_replaced(tmp_path: Path) -> None:
    real, link = tmp_path / "real.json", tmp_path / "link.json"
    real.write_text("old")
    link.symlink_to(real)
    write_atomic(link, "new")
    assert link.is_symlink() and real.read_text() == "new"
    fifo = tmp_path / "pipe"
    os.mkfifo(fifo)
    reader = subprocess.Popen(["cat", str(fifo)], stdout=subprocess.PIPE)
    write_atomic(fifo, "through the pipe")
    assert reader.communicate(timeout=30)[0] == b"through the pipe"
    assert stat.S_ISFIFO(os.stat(fifo).st_mode)
