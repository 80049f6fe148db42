"""Does the held moment relax as the food does?  The relaxation probe's contact, friction and
step against the truth, uncalibrated.

A contact in series with the food lengthens the held moment's decay, ``tau1 (1 + K2 / (K1 +
k_c))``, and soft friction lets the held faces creep; the calibration removes both on
average, but what it leaves is a per-food error.  This script measures how close one
relaxation clamp comes without any calibration, on the tuning foods only
(``TUNING_SEED``), with the ``measure`` probe's clamp and hold (one clamp, the full fit's
contact angle) under three physics settings:

* ``measure``: the base scene's 5 ms step, impratio 30, every contact stiffened with the
  food down to 1 ms (the committed uncalibrated tuning run, ``--base``);
* ``1 ms, impratio 1e4``: the same contact, friction nearly rigid (a held contact creeps
  ~ 1 / impratio) and a 1 ms step;
* ``precise``: that, with the blades' contact stiffened 300 times more
  (``ProbeConfig.relaxation_contact_ratio``; the plate's left alone, a cube's contact mesh
  5 x 5 x 5): the ``precise`` preset's physics.

For each shape it reports the median, 90th percentile and maximum of |g1| and |tau1| error,
the foods identified and the probes' CPU time.

    python benchmarks/relaxation_contact.py --n 256 --workers 2 \\
        --base docs/data/validation/tuning_measure_uncal_noise0.json

Each variant's records stream to ``--work`` (a stopped run continues from them); the summary
is written to ``--out`` (default ``docs/data/validation/relaxation_contact.json``).
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
from fetch_env.probes import PROBE_PRESETS

PRECISE = PROBE_PRESETS["precise"]
VARIANTS = {
    "1 ms, impratio 1e4": dataclasses.replace(
        BASE, relaxation_timestep=PRECISE.relaxation_timestep,
        relaxation_impratio=PRECISE.relaxation_impratio),
    "precise": dataclasses.replace(
        BASE, relaxation_timestep=PRECISE.relaxation_timestep,
        relaxation_impratio=PRECISE.relaxation_impratio,
        relaxation_contact_ratio=PRECISE.relaxation_contact_ratio),
}
SHAPES = ("cube", "ellipsoid", "sphere")
PARAMS = ("g1", "tau1")


def shape_summary(records: list[dict[str, Any]], shape: str) -> dict[str, Any]:
    """|error| of g1 and tau1 (median, 90th percentile, max), foods identified and the
    probes' median CPU time, over ``records`` of ``shape``."""
    mine = [r for r in records if r["food"]["shape"] == shape]
    ok = [r for r in mine if "crash" not in r and r["visco_valid"]
          and all(math.isfinite(r["error"][p]) for p in PARAMS)]
    out: dict[str, Any] = {"foods": len(mine), "identified": len(ok),
                           "cpu_probes_median": float(np.median([r["cpu_probes"] for r in ok]))
                           if ok else math.nan}
    for p in PARAMS:
        e = np.abs([r["error"][p] for r in ok])
        out[p] = ({"median": float(np.median(e)), "p90": float(np.percentile(e, 90)),
                   "max": float(e.max())} if len(e) else None)
    return out


def table(results: dict[str, dict[str, dict[str, Any]]]) -> str:
    """The summary as a Markdown table, one row a setting and shape."""
    rows = ["| setting | shape | identified | g1: median / 90th / max | "
            "tau1: median / 90th / max | CPU: probes a food |", "|---|---|---|---|---|---|"]
    for name, by_shape in results.items():
        for shape, s in by_shape.items():
            cells = [("-" if s[p] is None else
                      f"{100 * s[p]['median']:.2f} / {100 * s[p]['p90']:.1f} / "
                      f"{100 * s[p]['max']:.0f} %") for p in PARAMS]
            rows.append(f"| {name} | {shape} | {s['identified']} of {s['foods']} | "
                        + " | ".join(cells) + f" | {s['cpu_probes_median']:.2f} s |")
    return "\n".join(rows)


def main(argv: list[str] | None = None) -> int:
    args, base, foods = parse_tuning_args(__doc__.split("\n\n")[0], "relaxation_contact", argv)
    runs = {"measure": base}
    for name, config in VARIANTS.items():
        runs[name], stopped = run_variant(name, config, foods, args.work, args.workers)
        if stopped:
            print(f"relaxation_contact: {stopped}; {len(runs[name])} of {args.n} foods of "
                  f"{name!r} kept in {args.work} (rerun the same command to finish)",
                  file=sys.stderr)
            return 130 if "interrupted" in stopped else 1
    results = {name: {shape: shape_summary(recs, shape) for shape in SHAPES}
               for name, recs in runs.items()}
    summary = {"meta": {"set": "tuning", "seed": TUNING_SEED, "n": args.n,
                        "variants": {k: dataclasses.asdict(v) for k, v in VARIANTS.items()},
                        "command": "python benchmarks/relaxation_contact.py "
                        + " ".join(argv or sys.argv[1:])},
               "results": results}
    ve._write_atomic(args.out, json.dumps(summary, indent=1, default=float) + "\n")
    print(table(results))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
