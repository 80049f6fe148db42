"""Where each relaxation solve starts, before and after: the ``precise`` probes' simulations
of each food with MuJoCo's own warm start (``relaxation_warmstart="previous"``) and with the
alternating one the preset ships (``fetch_env.warmstart``), paired food by food in one
sitting.

Each task simulates one food's probes (every relaxation clamp and slide) both ways, in
either order by the food's index so that neither start always runs on a warmer cache, and
returns the CPU time of each in its worker and their Newton iterations (the relaxation
clamps' steps; the slides are the same both ways).  The ratio of the sums, the median of
the per-food ratios and the foods over the speed bar are printed and written as JSON.

    python benchmarks/bench_warmstart.py --set reporting --n 64 --workers 2 \\
        --out docs/data/bench_warmstart.json
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
import time
from pathlib import Path
from typing import Any

import mujoco
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import fetch_env.controller as controller
from benchmarks.readme_meta import meta, write_json
from benchmarks.validate_estimators import SETS, SPEED_BARS, foods_of
from fetch_env.food_space import Food
from fetch_env.parallel import run_ahead
from fetch_env.probes import PROBE_PRESETS, simulate_probes

STARTS = ("previous", "alternating")


class _IterationCount:
    """Counts the Newton iterations of every ``mj_step`` the controller takes while
    installed (a context manager: the controller's own step is put back on exit)."""

    def __init__(self) -> None:
        self.iterations = 0
        self._step = controller.mujoco.mj_step

    def __enter__(self) -> _IterationCount:
        def counted(m: mujoco.MjModel, d: mujoco.MjData) -> None:
            self._step(m, d)
            self.iterations += int(d.solver_niter[0])

        controller.mujoco.mj_step = counted
        return self

    def __exit__(self, *exc: object) -> None:
        controller.mujoco.mj_step = self._step


def _both_starts(food: Food, preset: str) -> dict[str, Any]:
    """A worker's task: the food's probe simulations with each start, their CPU times [s]
    and Newton iterations."""
    out: dict[str, Any] = {"index": food.index, "shape": food.shape, "size": food.size,
                           "young": food.young}
    order = STARTS if food.index % 2 == 0 else STARTS[::-1]
    for start in order:
        config = dataclasses.replace(PROBE_PRESETS[preset], relaxation_warmstart=start)
        with _IterationCount() as count:
            cpu = time.process_time()
            simulate_probes((food.piece(),), config)
            out[f"cpu_{start}"] = time.process_time() - cpu
        out[f"iterations_{start}"] = count.iterations
    return out


def summary(rows: list[dict[str, Any]], bar: float) -> dict[str, Any]:
    """Each start's median, 95th percentile and slowest CPU time, foods over ``bar``, and
    the ratios (alternating over previous) of the sums and per food."""
    out: dict[str, Any] = {}
    for start in STARTS:
        cpu = np.array([r[f"cpu_{start}"] for r in rows])
        slowest = int(np.argmax(cpu))
        out[start] = {"median_s": float(np.median(cpu)),
                      "p95_s": float(np.percentile(cpu, 95)),
                      "max_s": float(cpu[slowest]), "slowest_food": rows[slowest]["index"],
                      "over_bar": int((cpu > bar).sum()),
                      "iterations": int(sum(r[f"iterations_{start}"] for r in rows))}
    ratio = np.array([r["cpu_alternating"] / r["cpu_previous"] for r in rows])
    same = [r["index"] for r in rows if r["iterations_alternating"] == r["iterations_previous"]]
    out["ratio_of_sums"] = float(sum(r["cpu_alternating"] for r in rows)
                                 / sum(r["cpu_previous"] for r in rows))
    out["median_ratio"] = float(np.median(ratio))
    out["iteration_ratio"] = out["alternating"]["iterations"] / out["previous"]["iterations"]
    out["foods_with_equal_iterations"] = len(same)
    return out


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--set", choices=SETS, default="reporting")
    p.add_argument("--n", type=int, default=64)
    p.add_argument("--preset", choices=sorted(PROBE_PRESETS), default="precise")
    p.add_argument("--workers", type=int, default=1)
    p.add_argument("--out", type=Path, default=None)
    args = p.parse_args(argv)
    if not 1 <= args.n <= 4096 or args.workers < 1:
        p.error(f"--n {args.n} must be in [1, 4096] and --workers {args.workers} >= 1")
    foods = foods_of(args.set, args.n)
    wall = time.perf_counter()
    rows = run_ahead([(_both_starts, (f, args.preset)) for f in foods], args.workers)
    for r in rows:
        if isinstance(r, BaseException):
            raise r
    result = {"meta": meta(time.perf_counter() - wall), "set": args.set, "n": args.n,
              "preset": args.preset, "bar_s": SPEED_BARS["probes"],
              "summary": summary(rows, SPEED_BARS["probes"]), "foods": rows}
    print(json.dumps(result["summary"], indent=1))
    if args.out is not None:
        write_json(args.out, result)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
