"""``benchmarks/bench_fits.py``: each food's fits timed apart from its simulations, the
estimates those of the harness's committed records."""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from benchmarks.bench_fits import summarize

ROOT = Path(__file__).resolve().parents[1]
SCRIPT = ROOT / "benchmarks" / "bench_fits.py"


def test_summary_takes_each_foods_median_and_keeps_the_raw_spike() -> None:
    """One timing of food 1 at 5x its usual cost: the food's median stays at its cost, the
    raw maximum and count say the spike."""
    timings = np.array([[0.020, 0.030, 0.010],
                        [0.021, 0.150, 0.011],
                        [0.019, 0.031, 0.012]])
    s = summarize(timings, bar=0.05)
    assert s["max"] == pytest.approx(0.031) and s["slowest_position"] == 1
    assert s["median"] == pytest.approx(0.020)
    assert s["over_bar"] == 0
    assert (s["raw_max"], s["raw_over_bar"], s["raw_count"]) == (pytest.approx(0.150), 1, 9)


def test_a_food_fitted_as_the_harness_committed(tmp_path: Path) -> None:
    """Reporting food 0, ``precise`` probes (~6 s of simulation): every pass gives the
    estimates of the committed harness run bit for bit, at both noise levels, and the fits
    are timed apart from the simulations (well under the 50 ms bar)."""
    out = tmp_path / "fits.json"
    run = subprocess.run(
        [sys.executable, str(SCRIPT), "--n", "1", "--preset", "precise", "--noise", "0", "0.01",
         "--repeats", "2", "--check-against", str(ROOT / "docs" / "data" / "validation"),
         "--out", str(out)], capture_output=True, text=True, timeout=300, cwd=ROOT)
    assert run.returncode == 0, run.stderr[-2000:]
    data = json.loads(out.read_text())
    assert sorted(data["fits"]) == ["0", "0.01"]
    for fits in data["fits"].values():
        assert np.shape(fits["timings_s"]) == (2, 1)
        assert fits["passes_differing"] == 0
        assert (fits["committed_compared"], fits["committed_differing"]) == (1, [])
        assert all(t > 0.0 for row in fits["timings_s"] for t in row)  # (the 50 ms bar is
        # the benchmark's to report, not a timed test's on a shared machine)
    assert len(data["simulations_cpu_s"]) == 1 and data["simulations_cpu_s"][0] > 1.0
    assert run.stdout.count("estimates as committed on 1 of 1 foods") == 2


@pytest.mark.parametrize(("args", "says"), [
    (["--repeats", "0"], "--repeats must be >= 1, got 0"),
    (["--noise", "0.7"], "--noise must be in [0, 0.5], got 0.7"),
    (["--check-against", "no/such/folder"], "--check-against: no folder no/such/folder"),
])
def test_bad_arguments_one_line_before_any_work(args: list[str], says: str) -> None:
    run = subprocess.run([sys.executable, str(SCRIPT), *args], capture_output=True,
                         text=True, timeout=60, cwd=ROOT)
    assert run.returncode == 2
    assert says in run.stderr
    assert "Traceback" not in run.stderr


def test_a_missing_committed_run_is_refused_before_any_simulation(tmp_path: Path) -> None:
    """--check-against names the harness's run it lacks, in one line, before simulating."""
    run = subprocess.run([sys.executable, str(SCRIPT), "--noise", "0", "0.01",
                          "--check-against", str(tmp_path)], capture_output=True, text=True,
                         timeout=60, cwd=ROOT)
    assert run.returncode == 2
    assert f"--check-against: no {tmp_path / 'reporting_precise_noise0.json'}" in run.stderr
    assert "Traceback" not in run.stderr and run.stdout == ""


def test_a_stop_mid_simulation_is_one_line_and_leaves_the_old_file(tmp_path: Path) -> None:
    """SIGTERM while the workers simulate: one line, exit 143, ``--out`` as it was."""
    out = tmp_path / "fits.json"
    out.write_text("{}\n")
    proc = subprocess.Popen([sys.executable, str(SCRIPT), "--n", "4", "--workers", "2",
                             "--out", str(out)], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, cwd=ROOT)
    deadline = time.monotonic() + 60.0
    while not _children(proc.pid) and time.monotonic() < deadline:
        time.sleep(0.05)
    time.sleep(0.5)
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 128 + signal.SIGTERM, err
    assert err.strip().splitlines() == [
        "bench_fits: stopped (SIGTERM) before every food was timed; nothing written (a "
        "figure needs every food)"], err
    assert out.read_text() == "{}\n"


def _children(pid: int) -> list[str]:
    return [c for task in Path(f"/proc/{pid}/task").glob("*")
            for c in (task / "children").read_text().split()]
