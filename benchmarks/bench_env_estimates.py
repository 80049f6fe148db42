"""The environments' model estimates against their oracle, and what the probes cost a reset.

For each layout, resets the env on held-back seeds (Block: ``tests/test_env_slow.HELD_BACK``,
90000-90063; the other layouts: 90000-90031) with the default ``env`` probes calibrated and
uncalibrated (``probe_calibrated``) and with the ``measure`` and ``repeated`` probes
calibrated (``probes="measure"``, ``probes="repeated"``; where a preset has a calibration
fitted on the layout's own scenes, which the env applies, also with the food-space one), and
reports, per parameter, the
median, 95th percentile and max of |model / oracle - 1| (g1, tau1 and mu: the material's,
exact; K1, K2, B: the oracle's nominal ``2 E A / l``, so only their scatter means much, and
against the probed piece's elastic twin under the variant's probe, ``errors_twin``: the
truth the estimators are validated against, the env's ``true_stiffness="elastic_twin"``,
computed outside the timed reset), the probes' median wall time per reset and the reset's
median CPU time (this process's, so the machine's load does not enter).  Writes JSON and a
markdown table.  The scenes are the "study" space's (the -v0 ids'); ``--scenes`` draws
another space's (``fetch_env.env_scenes.SCENE_SPACES``) and names the files after it.

    python benchmarks/bench_env_estimates.py --workers 2 --out docs/data/validation
    python benchmarks/bench_env_estimates.py --layouts row --scenes any_shape --workers 2
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from agents.atomic import write_atomic
from benchmarks.validate_estimators import reliability_tally
from fetch_env.env import FoodFetchEnv
from fetch_env.env_scenes import SCENE_SPACES
from fetch_env.errors import SimulationDivergedError
from fetch_env.probes import (
    PARAM_NAMES,
    PROBE_CALIBRATIONS,
    calibration_for,
    true_parameters_exact,
)

STIFFNESS = ("K1", "K2", "B")

LAYOUTS = {"block": 64, "row": 32, "two_rows": 32, "diced": 32}
FIRST_SEED = 90_000


# (probes preset, calibrated) per layout; where a preset has a calibration fitted on the
# layout's own scenes (fetch_env.probes.calibration_for), the env applies that one, and the
# preset is also run with its food-space calibration, to compare
VARIANTS: tuple[tuple[str, bool], ...] = (("env", True), ("env", False), ("measure", True),
                                          ("repeated", True))


def run(layout: str, probes: str, calibrated: bool, seeds: list[int],
        scenes: str = "study", food_space: bool = False) -> dict[str, Any]:
    """Reset on every seed; the errors per parameter, the probes' wall times and the
    resets' CPU times.  ``food_space``: apply the preset's food-space calibration even where
    the env would apply one fitted on the layout's scenes."""
    env = FoodFetchEnv(layout=layout, estimator="model", probes=probes,
                       probe_calibrated=calibrated, scenes=scenes)
    if food_space:
        env.probe_calibration = PROBE_CALIBRATIONS[probes]
    cal = env.probe_calibration
    label = ("no" if cal is None else "food space" if cal is PROBE_CALIBRATIONS.get(probes)
             else f"{layout} scenes")
    errs: dict[str, list[float]] = {k: [] for k in PARAM_NAMES}
    errs_twin: dict[str, list[float]] = {k: [] for k in STIFFNESS}
    walls, cpus, reliable = [], [], []
    for seed in seeds:
        cpu = time.process_time()
        _, info = env.reset(seed=seed)
        cpus.append(time.process_time() - cpu)
        walls.append(env.last_probe_wall_time)
        reliable.append(bool(info["probe_reliable"]))
        for k in PARAM_NAMES:
            est = info["estimated_params"][k]
            errs[k].append(float("nan") if est is None else est / info["true_params"][k] - 1)
        twin = _twin_truth(env, info["probe_piece"])
        for k in STIFFNESS:
            est = info["estimated_params"][k]
            errs_twin[k].append(float("nan") if est is None or twin is None
                                else est / twin[k] - 1)
    return {"layout": layout, "scenes": scenes, "probes": probes, "calibrated": calibrated,
            "calibration": label,
            "seeds": [seeds[0], seeds[-1]], "errors": errs, "errors_twin": errs_twin,
            "reliable": reliable,
            "wall_median": float(np.median(walls)), "reset_cpu_median": float(np.median(cpus))}


def _twin_truth(env: FoodFetchEnv, k: int) -> dict[str, float] | None:
    """The probed piece's true K1, K2, B from its elastic twin under the env's probe, as
    the env gives them with ``true_stiffness="elastic_twin"`` (None where the twin is held
    at no placement)."""
    try:  # the twin is placed where the probes clamp (elastic_stiffness)
        return true_parameters_exact(env.pieces[k], env.probe_config, env.geometry)
    except SimulationDivergedError:
        return None


def summary(errs: list[float]) -> dict[str, float]:
    e = np.abs(np.array(errs, dtype=float))
    ok = e[np.isfinite(e)]
    if not ok.size:
        return {"found": 0, "median": float("nan"), "p95": float("nan"), "max": float("nan")}
    return {"found": int(ok.size), "median": float(np.median(ok)),
            "p95": float(np.percentile(ok, 95)), "max": float(ok.max())}


def reliable_tally(r: dict[str, Any]) -> dict[str, int] | None:
    """``info["probe_reliable"]`` against the errors, scene by scene, as the validation
    harness counts its foods (:func:`benchmarks.validate_estimators.reliability_tally`:
    misses over 5 % called reliable, scenes within 2 % flagged); None for a run recorded
    without the flag."""
    if "reliable" not in r:
        return None
    scenes = [{"error": {k: r["errors"][k][i] for k in ("g1", "tau1", "mu")}, "reliable": flag}
              for i, flag in enumerate(r["reliable"])]
    return reliability_tally(scenes)


def reliable_counts(r: dict[str, Any]) -> str:
    """:func:`reliable_tally` as the table's cell, "a of b / c of d" ("-" without it)."""
    t = reliable_tally(r)
    if t is None:
        return "-"
    return (f"{t['over_5pct_flagged_reliable']} of {t['n_over_5pct']} / "
            f"{t['under_2pct_flagged_unreliable']} of {t['n_under_2pct']}")


def table(results: list[dict[str, Any]]) -> str:
    lines = ["| layout | probes | calibration | scenes | " + " | ".join(
        f"{k} median / 95th" for k in ("g1", "tau1", "mu"))
        + " | K1 median / 95th, elastic twin | reliable: misses > 5 % called reliable / "
        "good < 2 % flagged | reset CPU | against env probes |",
        "|---|---|---|---|---|---|---|---|---|---|---|"]
    base = {r["layout"]: r["reset_cpu_median"] for r in results
            if r["probes"] == "env" and r["calibrated"]}
    for r in results:
        cells = []
        for k in ("g1", "tau1", "mu"):
            s = summary(r["errors"][k])
            cells.append(f"{100 * s['median']:.1f} / {100 * s['p95']:.1f} %")
        twin = r.get("errors_twin", {}).get("K1")
        s = summary(twin) if twin else None
        cells.append(f"{100 * s['median']:.1f} / {100 * s['p95']:.1f} %" if s and s["found"]
                     else "-")
        n = len(r["errors"]["g1"])
        cpu, ref = r["reset_cpu_median"], base.get(r["layout"])
        ratio = f"{cpu / ref:.2f}x" if ref else ""
        label = r.get("calibration", "food space" if r["calibrated"] else "no")
        lines.append(f"| {r['layout']} | {r['probes']} | {label} | {n} | " + " | ".join(cells)
                     + f" | {reliable_counts(r)} | {1e3 * cpu:.0f} ms | {ratio} |")
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--workers", type=int, default=1)
    p.add_argument("--out", type=Path, default=Path("docs/data/validation"))
    p.add_argument("--layouts", nargs="+", choices=sorted(LAYOUTS), default=list(LAYOUTS))
    p.add_argument("--scenes", choices=SCENE_SPACES, default="study",
                   help="scene space drawn at reset (default: the -v0 ids' study space)")
    args = p.parse_args(argv)
    if args.workers < 1:
        p.error("--workers must be >= 1")
    jobs = []
    for lay in args.layouts:
        seeds = list(range(FIRST_SEED, FIRST_SEED + LAYOUTS[lay]))
        for probes, cal in VARIANTS:
            jobs.append((lay, probes, cal, seeds, args.scenes, False))
            own = calibration_for(probes, lay, args.scenes)
            if cal and own is not PROBE_CALIBRATIONS.get(probes):
                jobs.append((lay, probes, cal, seeds, args.scenes, True))
    with ProcessPoolExecutor(args.workers) as pool:
        results = list(pool.map(run, *zip(*jobs, strict=True)))
    meta = {"machine": platform.machine(), "cpus": os.cpu_count(),
            "python": platform.python_version(),
            "command": "python benchmarks/bench_env_estimates.py " + " ".join(argv or sys.argv[1:])}
    for r in results:
        r["summary"] = {k: summary(r["errors"][k]) for k in PARAM_NAMES}
        r["summary_twin"] = {k: summary(r["errors_twin"][k]) for k in STIFFNESS}
    args.out.mkdir(parents=True, exist_ok=True)
    text = json.dumps({"meta": meta, "results": results}, indent=1)
    name = "env_estimates" if args.scenes == "study" else f"env_estimates_{args.scenes}"
    write_atomic(args.out / f"{name}.json", text)
    md = table(results)
    write_atomic(args.out / f"{name}.md", md)
    print(md)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
