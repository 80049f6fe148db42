"""Is the probes' miss on a food chaos or bias?  The measure probes on twins of each food.

A simulated clamp can be chaotic: the study's probe on its own cube reads tau1 several per
cent apart when the piece moves 1 um (``study_food_floor.py``).  Where a probe's miss is
such chaos, repeating the probe with the food placed a hair differently and averaging
would shrink it, and the repeats' spread would say how far each food is off.  Where it is
a bias of the food, the repeats agree and neither helps.

This script measures which, on the tuning foods only (``TUNING_SEED``; the reporting foods
stay untouched): the ``measure`` probe on each food as placed (the committed uncalibrated
tuning run, ``--base``) and with the blades' approach gap (``Geometry.gap``, 1 mm) moved by
+1, -1 and +2 um, each calibrated by 8-fold cross-validation as ``second_clamp.py`` does.
For g1, tau1, mu and K1 it reports the median and 95th percentile of the twins' spread
(the standard deviation of a food's log-estimate over the four placements), of the |error|
as placed and of the |error| of the four placements' mean, and the share of the
log-errors' variance that lies within foods (1: all chaos, 0: all bias).

    python benchmarks/probe_twins.py --n 256 --workers 2 \\
        --base docs/data/validation/tuning_measure_uncal_noise0.json

Each twin's records stream to ``--work`` (a stopped run continues from them); the summary
is written to ``--out`` (default ``docs/data/validation/probe_twins.json``).
"""

from __future__ import annotations

import dataclasses
import json
import math
import sys
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))

import validate_estimators as ve
from second_clamp import BASE, parse_tuning_args, run_variant

from fetch_env.food_space import TUNING_SEED
from fetch_env.scene import Geometry

DEFAULT_GEOMETRY = Geometry()
# the twins: the approach gap moved by these [m]
TWIN_GAP_MOVES: dict[str, float] = {"gap +1 um": 1e-6, "gap -1 um": -1e-6, "gap +2 um": 2e-6}
PARAMS = ("g1", "tau1", "mu", "K1")


def log_errors(held: dict[str, dict[int, dict[str, Any]]], param: str) -> np.ndarray:
    """log(estimate / truth) of ``param``, placements (rows) by food (columns), over the
    foods every placement measured."""
    names = list(held)
    common = sorted(set.intersection(*(set(h) for h in held.values())))
    out = np.full((len(names), len(common)), math.nan)
    for i, n in enumerate(names):
        for j, k in enumerate(common):
            r = held[n][k]
            v = r.get("estimate", {}).get(param, math.nan)
            if math.isfinite(v) and v > 0:
                out[i, j] = math.log(v / r["truth"][param])
    return out[:, np.isfinite(out).all(axis=0)]


def summary_of(errors: np.ndarray) -> dict[str, Any]:
    """Spread over the placements, errors as placed and of the mean, and the within-food
    share of the variance, for one parameter's log-errors (placements x foods)."""
    spread = errors.std(axis=0, ddof=1)
    placed, mean = np.abs(errors[0]), np.abs(errors.mean(axis=0))
    total = float(errors.var(ddof=1))
    within = float(errors.var(axis=0, ddof=1).mean())

    def q(x: np.ndarray) -> dict[str, float]:
        return {"median": float(np.median(x)), "p95": float(np.percentile(x, 95))}

    return {"foods": int(errors.shape[1]), "spread": q(spread), "as_placed": q(placed),
            "mean": q(mean), "within_share": within / total if total > 0 else math.nan}


def table(results: dict[str, dict[str, Any]]) -> str:
    """The summary as a Markdown table, one row a parameter."""
    rows = ["| parameter | foods | twins' spread, median / 95th | abs error as placed, median / "
            "95th | abs error of the 4 placements' mean | variance within foods |",
            "|---|---|---|---|---|---|"]
    for p, r in results.items():
        cells = [f"{100 * r[k]['median']:.2f} / {100 * r[k]['p95']:.2f} %"
                 for k in ("spread", "as_placed", "mean")]
        rows.append(f"| {p} | {r['foods']} | " + " | ".join(cells)
                    + f" | {100 * r['within_share']:.0f} % |")
    return "\n".join(rows)


def main(argv: list[str] | None = None) -> int:
    args, base, foods = parse_tuning_args(__doc__.split("\n\n")[0], "probe_twins", argv)
    runs = {"as placed": base}
    for name, move in TWIN_GAP_MOVES.items():
        geometry = dataclasses.replace(DEFAULT_GEOMETRY, gap=DEFAULT_GEOMETRY.gap + move)
        runs[name], stopped = run_variant(name, BASE, foods, args.work, args.workers, geometry)
        if stopped:
            print(f"probe_twins: {stopped}; {len(runs[name])} of {args.n} foods of {name!r} "
                  f"kept in {args.work} (rerun the same command to finish)", file=sys.stderr)
            return 130 if "interrupted" in stopped else 1
    # in food order, so that the fits' sums, and so their last bits, do not depend on the
    # order in which the workers finished
    runs = {k: sorted(v, key=lambda r: int(r["food"]["index"])) for k, v in runs.items()}
    held = {name: {int(r["food"]["index"]): r
                   for r in ve.cross_validate(recs, [recs])[0]["records"]}
            for name, recs in runs.items()}
    results = {param: summary_of(log_errors(held, param)) for param in PARAMS}
    summary = {"meta": {"set": "tuning", "seed": TUNING_SEED, "n": args.n,
                        "gap_moves_m": TWIN_GAP_MOVES,
                        "command": "python benchmarks/probe_twins.py "
                        + " ".join(argv or sys.argv[1:])},
               "results": results}
    ve._write_atomic(args.out, json.dumps(summary, indent=1, default=float) + "\n")
    print(table(results))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
