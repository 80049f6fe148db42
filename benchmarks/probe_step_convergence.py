"""Does the relaxation probe's g1 and tau1 converge to the material's as the physics step
shrinks?  The floor the simulated measurement sets over the food space.

Runs the ``measure`` probes (the relaxation hold of ``food-fetch estimate``) on the first
``--foods`` tuning foods (``fetch_env.food_space.TUNING_SEED``), once per relaxation physics
step in ``--steps``, without the probe calibration (it was fitted at the default 5 ms step),
and holds the estimates of g1 and tau1 to the material's.  Two things follow per step:

* the error left as the step shrinks: if it went to zero, the per-food error the calibration
  leaves would be the coarse step's, and a finer step would remove it;
* how far one food's estimate moves between steps that are all fine enough for the contact
  (its spread over the steps): a change of numerics, not of physics, so that spread is a
  floor under the per-food error no calibration can remove.

Prints a table and writes JSON and the table (markdown) under ``--out``:

    python benchmarks/probe_step_convergence.py --foods 24 --workers 2 --out docs/data/probe_steps
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import os
import platform
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from fetch_env.food_space import TUNING_SEED, sample_foods
from fetch_env.probes import PROBE_PRESETS, run_probes

DEFAULT_STEPS = (0.005, 0.0025, 0.001, 0.0005, 0.00025)
PARAMS = ("g1", "tau1")


def one(index: int, n_foods: int, step: float) -> dict[str, Any]:
    """The uncalibrated ``measure`` probes of tuning food ``index`` at one physics step."""
    food = sample_foods(n_foods, TUNING_SEED)[index]
    config = dataclasses.replace(PROBE_PRESETS["measure"], relaxation_timestep=step)
    cpu = time.process_time()
    rec: dict[str, Any] = {"index": index, "step": step, "food": food.to_dict()}
    try:
        out = run_probes((food.piece(),), config, noise=0.0, seed=0, calibration=None)
    except Exception as exc:  # a sweep keeps going; the record says what failed
        rec["crash"] = f"{type(exc).__name__}: {exc}"
        return rec
    truth = {"g1": food.g1, "tau1": food.tau1}
    rec["error"] = {k: out.estimates[k] / truth[k] - 1 for k in PARAMS}
    rec["cpu_s"] = time.process_time() - cpu
    return rec


def _finite(records: list[dict[str, Any]], key: str) -> np.ndarray:
    vals = [r["error"][key] for r in records if "error" in r]
    return np.array([v for v in vals if math.isfinite(v)])


def summarize(records: list[dict[str, Any]], steps: tuple[float, ...]) -> dict[str, Any]:
    """Per step: foods measured, median signed and median and 95th-percentile |error|, the
    CPU of a probe; per food: the spread (standard deviation of log(estimate)) over the steps
    of 1 ms and finer, its median and 95th percentile over the foods."""
    rows = []
    for step in steps:
        rs = [r for r in records if r["step"] == step]
        row: dict[str, Any] = {"step": step, "foods": len(rs),
                               "measured": sum(1 for r in rs if "error" in r
                                               and all(math.isfinite(v)
                                                       for v in r["error"].values())),
                               "cpu_s_median": float(np.median([r["cpu_s"] for r in rs
                                                                if "cpu_s" in r]))}
        for k in PARAMS:
            e = _finite(rs, k)
            row[k] = {"median_signed": float(np.median(e)), "median_abs": float(np.median(abs(e))),
                      "p95_abs": float(np.percentile(abs(e), 95))}
        rows.append(row)
    fine = [s for s in steps if s <= 0.001 + 1e-12]
    spread: dict[str, Any] = {"steps": fine}
    for k in PARAMS:
        sds = []
        for idx in sorted({r["index"] for r in records}):
            logs = [math.log1p(r["error"][k]) for r in records
                    if r["index"] == idx and r["step"] in fine and "error" in r
                    and math.isfinite(r["error"][k]) and r["error"][k] > -1]
            if len(logs) == len(fine) >= 2:
                sds.append(float(np.std(logs, ddof=1)))
        spread[k] = {"foods": len(sds), "median": float(np.median(sds)) if sds else None,
                     "p95": float(np.percentile(sds, 95)) if sds else None}
    return {"rows": rows, "spread": spread}


def table(summary: dict[str, Any]) -> str:
    """The summary as a markdown table, one row a step, and the spread line."""
    lines = ["| physics step | foods measured | g1 median error (signed) | g1 median / 95th "
             "pct abs error | tau1 median error (signed) | tau1 median / 95th pct abs error "
             "| CPU a probe |", "|---|---|---|---|---|---|---|"]
    for r in summary["rows"]:
        g, t = r["g1"], r["tau1"]
        lines.append(f"| {1e3 * r['step']:g} ms | {r['measured']} of {r['foods']} "
                     f"| {100 * g['median_signed']:+.2f} % | {100 * g['median_abs']:.2f} / "
                     f"{100 * g['p95_abs']:.1f} % | {100 * t['median_signed']:+.2f} % "
                     f"| {100 * t['median_abs']:.2f} / {100 * t['p95_abs']:.1f} % "
                     f"| {r['cpu_s_median']:.2f} s |")
    s = summary["spread"]
    steps = ", ".join(f"{1e3 * x:g}" for x in s["steps"])
    lines.append(f"\nOne food's estimate over the steps of {steps} ms (standard deviation of "
                 f"log(estimate), over {s['tau1']['foods']} foods): g1 median "
                 f"{100 * s['g1']['median']:.2f} %, 95th percentile {100 * s['g1']['p95']:.1f} %; "
                 f"tau1 median {100 * s['tau1']['median']:.2f} %, 95th percentile "
                 f"{100 * s['tau1']['p95']:.1f} %.")
    return "\n".join(lines) + "\n"


def _steps(text: str) -> tuple[float, ...]:
    """``--steps``: at least two relaxation steps, each one ``ProbeConfig`` accepts."""
    try:
        steps = tuple(float(x) for x in text.split(","))
        for s in steps:
            dataclasses.replace(PROBE_PRESETS["measure"], relaxation_timestep=s)
    except ValueError as exc:  # InvalidParameterError is a ValueError
        raise argparse.ArgumentTypeError(f"--steps {text!r}: {exc}") from None
    if len(steps) < 2:
        raise argparse.ArgumentTypeError(f"--steps {text!r}: give at least two steps")
    return steps


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--foods", type=int, default=24, help="first N tuning foods (default 24)")
    p.add_argument("--steps", type=_steps, default=DEFAULT_STEPS,
                   help="relaxation physics steps [s], comma-separated")
    p.add_argument("--workers", type=int, default=1)
    p.add_argument("--out", type=Path, default=Path("docs/data/probe_steps"))
    args = p.parse_args(argv)
    if args.foods < 2 or args.workers < 1:
        p.error(f"--foods {args.foods} must be >= 2 and --workers {args.workers} >= 1")
    jobs = [(i, args.foods, s) for i in range(args.foods) for s in args.steps]
    start = time.perf_counter()
    with ProcessPoolExecutor(args.workers) as pool:
        records = list(pool.map(one, *zip(*jobs, strict=True)))
    summary = summarize(records, args.steps)
    meta = {"machine": platform.machine(), "cpus": os.cpu_count(),
            "python": platform.python_version(), "seed": TUNING_SEED,
            "wall_s": time.perf_counter() - start,
            "command": "python benchmarks/probe_step_convergence.py "
                       + " ".join(argv if argv is not None else sys.argv[1:])}
    args.out.mkdir(parents=True, exist_ok=True)
    payload = json.dumps({"meta": meta, "summary": summary, "records": records}, indent=1)
    for name, text in (("convergence.json", payload), ("convergence.md", table(summary))):
        tmp = args.out / (name + ".tmp")
        tmp.write_text(text)
        os.replace(tmp, args.out / name)
    print(table(summary))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
