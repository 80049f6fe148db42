"""The study's own food at its four clamp speeds, and the floor the simulation sets.

Runs the study's probe (``food-fetch estimate --probes study``: theta_d 0.0244 rad, a 25 s
hold, the full fit) on the study's 15 mm, 0.2 MPa cube (g1 0.425, tau1 3.667 s) at omega
0.01, 0.02, 0.03 and 0.04 rad/s, each on the piece as placed and on ``--twins`` copies moved
by 1, 2, ... um along the blade (x): a move far below anything physical, so the spread of
the estimates over the twins is the simulation's own floor on how well g1 and tau1 can be
measured.  Prints a table and writes JSON.

    python benchmarks/study_food_floor.py --twins 4 --workers 2 --out docs/data/study_food
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import platform
import sys
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from fetch_env.layouts import Piece
from fetch_env.materials import Material
from fetch_env.study_probes import RELAXATION_DEFAULTS, run_relaxation_probe

OMEGAS = (0.01, 0.02, 0.03, 0.04)
G1, TAU1 = 0.425, 3.667
STUDY = {"g1": 0.00941, "tau1": 0.00164}  # the study's largest deviations


def one(omega: float, shift_um: int) -> dict[str, Any]:
    piece = dataclasses.replace(Piece("cube", 0.015, Material(young=0.2e6, g1=G1, tau1=TAU1)),
                                x=shift_um * 1e-6)
    r = run_relaxation_probe((piece,), RELAXATION_DEFAULTS["theta_d"], omega,
                             RELAXATION_DEFAULTS["hold"])
    est = r["estimate"]
    return {"omega": omega, "shift_um": shift_um,
            "g1": None if est is None else est.g1, "tau1": None if est is None else est.tau1,
            "error": r["error"]}


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--twins", type=int, default=4)
    p.add_argument("--workers", type=int, default=1)
    p.add_argument("--out", type=Path, default=Path("docs/data/study_food"))
    args = p.parse_args(argv)
    if args.twins < 1 or args.workers < 1:
        p.error("--twins and --workers must be >= 1")
    jobs = [(w, k) for w in OMEGAS for k in range(args.twins + 1)]
    with ProcessPoolExecutor(args.workers) as pool:
        runs = list(pool.map(one, *zip(*jobs, strict=True)))
    rows = []
    lines = ["| omega [rad/s] | g1 error, as placed | g1 spread over 1 um twins | tau1 error, "
             "as placed | tau1 spread over 1 um twins |", "|---|---|---|---|---|"]
    for w in OMEGAS:
        rs = [r for r in runs if r["omega"] == w and r["g1"] is not None]
        g = np.array([r["g1"] / G1 - 1 for r in rs])
        t = np.array([r["tau1"] / TAU1 - 1 for r in rs])
        base = next((r for r in rs if r["shift_um"] == 0), None)
        row = {"omega": w, "n": len(rs), "g1_error": None if base is None else base["g1"] / G1 - 1,
               "tau1_error": None if base is None else base["tau1"] / TAU1 - 1,
               "g1_spread": float(g.max() - g.min()), "tau1_spread": float(t.max() - t.min())}
        rows.append(row)
        lines.append(f"| {w:g} | {100 * row['g1_error']:+.2f} % | {100 * row['g1_spread']:.2f} % "
                     f"| {100 * row['tau1_error']:+.2f} % | {100 * row['tau1_spread']:.2f} % |")
    lines.append(f"\nThe study's largest deviations: g1 {100 * STUDY['g1']:.3f} %, tau1 "
                 f"{100 * STUDY['tau1']:.3f} %. {args.twins} twins a speed.")
    meta = {"machine": platform.machine(), "cpus": os.cpu_count(),
            "python": platform.python_version(),
            "command": "python benchmarks/study_food_floor.py " + " ".join(argv or sys.argv[1:])}
    args.out.mkdir(parents=True, exist_ok=True)
    tmp = args.out / "floor.json.tmp"
    tmp.write_text(json.dumps({"meta": meta, "rows": rows, "runs": runs}, indent=1))
    os.replace(tmp, args.out / "floor.json")
    (args.out / "floor.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
