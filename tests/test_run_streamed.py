"""The harnesses' streamed pool (benchmarks.validate_estimators.run_streamed): a stop keeps
every finished record, a second stop signal during the shutdown is ignored, the signal
handlers in place before are back afterwards, and the exit code names the stop."""

from __future__ import annotations

import argparse
import json
import os
import signal
import threading
import time
from pathlib import Path
from typing import Any

import pytest

from benchmarks import slip_probe
from benchmarks.validate_estimators import _write_results, run_streamed


def _slow_record(i: int) -> dict[str, Any]:
    time.sleep(0.05 if i < 2 else 5.0)
    return {"food": {"index": i}}


def test_two_sigterms_keep_the_finished_records_and_restore_the_handlers(
        tmp_path: Path) -> None:
    jsonl = tmp_path / "records.jsonl"
    records: list[dict[str, Any]] = []
    before = signal.getsignal(signal.SIGTERM)

    def stop_twice() -> None:
        while len(records) < 2:
            time.sleep(0.01)
        os.kill(os.getpid(), signal.SIGTERM)
        os.kill(os.getpid(), signal.SIGTERM)

    threading.Thread(target=stop_twice, daemon=True).start()
    stopped = run_streamed(_slow_record, [(i,) for i in range(4)], 2, jsonl, records)
    assert stopped == "interrupted (SIGTERM)"
    assert sorted(r["food"]["index"] for r in records) == [0, 1]
    lines = [json.loads(line) for line in jsonl.read_text().splitlines()]
    assert sorted(r["food"]["index"] for r in lines) == [0, 1]
    assert signal.getsignal(signal.SIGTERM) == before


@pytest.mark.parametrize(("stopped", "code"), [
    ("interrupted (SIGINT)", 130), ("interrupted (SIGTERM)", 143),
    ("interrupted (SIGHUP)", 129), ("a worker process died", 1)])
def test_a_stopped_harness_exits_128_plus_the_signal(
        tmp_path: Path, stopped: str, code: int, capsys: pytest.CaptureFixture[str]) -> None:
    """The harness's exit code after a stop, as a shell reports a process the signal
    killed; 1 for a lost worker. The line on stderr says why and where the foods are."""
    args = argparse.Namespace(n=64, out=tmp_path)
    jsonl = tmp_path / "run.jsonl"
    assert _write_results(args, "run", [], {}, jsonl, stopped) == code
    err = capsys.readouterr().err
    assert err.strip() == (f"validate_estimators: {stopped}; 0 of 64 foods finished, kept in "
                           f"{jsonl} (rerun with --resume to finish)")


@pytest.mark.parametrize(("stopped", "code"), [
    ("interrupted (SIGTERM)", 143), ("interrupted (SIGHUP)", 129),
    ("a worker process died", 1)])
def test_a_stopped_slip_probe_benchmark_exits_as_the_harness_does(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch, stopped: str, code: int) -> None:
    """benchmarks/slip_probe.py streams through the same pool and exits with the same code
    for the same stop (it gave 130 for any signal)."""
    monkeypatch.setattr(slip_probe, "run_variant", lambda *a: ([], stopped))
    assert slip_probe.main(["--n", "16", "--work", str(tmp_path)]) == code

