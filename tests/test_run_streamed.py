"""The harnesses' streamed pool (benchmarks.validate_estimators.run_streamed): a stop keeps
every finished record, a second stop signal during the shutdown is ignored, and the signal
handlers in place before are back afterwards."""

from __future__ import annotations

import json
import os
import signal
import threading
import time
from pathlib import Path
from typing import Any

from benchmarks.validate_estimators import run_streamed


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
