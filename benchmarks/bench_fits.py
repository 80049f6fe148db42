"""The cost of one food's estimate, its two parts timed apart: the probes' simulations, and
the fits (both estimators, the intervals, the calibration; target under 50 ms a food).

The validation harness times each food once, inside a run that simulates between the
fits; on a shared machine a timing can come out several times the food's usual cost (a
food whose fits take 20 ms timed at 105 ms once, and at 20 ms when run again).  Here
each food's probes are simulated once (:func:`fetch_env.probes.simulate_probes`, on
``--workers`` processes, the CPU time of each simulation taken in its worker), then this
process fits every food ``--repeats`` times, in interleaved passes over all the foods, so
that a disturbance lands in one pass rather than in every timing of a food.  A food's fits
cost is the median of its timings; the raw maximum and every timing are kept beside it.

Each pass must give the same estimates, and, with ``--check-against``, the estimates the
harness committed for those foods (``benchmarks/validate_estimators.py``): the timed fits
are the measured ones.  They are compared bit for bit where numpy dispatches the kernels the
committed runs were written with, and to 2 % elsewhere (``benchmarks/reproducibility.py``).

    python benchmarks/bench_fits.py --set reporting --n 64 --preset precise --noise 0 0.01 \\
        --repeats 5 --workers 2 --check-against docs/data/validation --out docs/data/bench_fits.json
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

# Benchmark this checkout's package, not whatever copy happens to be installed.
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks.readme_meta import meta, write_json
from benchmarks.reproducibility import committed_rtol, kernels_note
from benchmarks.validate_estimators import SETS, SPEED_BARS, food_seed, foods_of
from fetch_env.food_space import Food
from fetch_env.parallel import WorkerLostError, run_ahead, stop_exit_code, stop_on_signals
from fetch_env.probes import (
    PROBE_CALIBRATIONS,
    PROBE_PRESETS,
    ProbeRuns,
    run_probes,
    simulate_probes,
)


def _simulate_timed(food: Food, preset: str) -> tuple[ProbeRuns, float]:
    """A worker's task: the food's probe simulations and their CPU time there [s]."""
    start = time.process_time()
    runs = simulate_probes((food.piece(),), PROBE_PRESETS[preset])
    return runs, time.process_time() - start


def simulate(foods: list[Food], preset: str, workers: int) -> list[tuple[ProbeRuns, float]]:
    """Every food's simulations, in the foods' order (a food whose simulation raised
    raises here: the probes catch the physics' own failures, so that is a bug)."""
    results = run_ahead([(_simulate_timed, (f, preset)) for f in foods], workers)
    for food, res in zip(foods, results, strict=True):
        if isinstance(res, BaseException):
            raise RuntimeError(f"food {food.index}: {type(res).__name__}: {res}") from res
    return results


def fit_once(food: Food, runs: ProbeRuns, preset: str, noise: float
             ) -> tuple[float, dict[str, float]]:
    """The fits' CPU time [s] and the estimates, as the harness fits this food."""
    out = run_probes((food.piece(),), PROBE_PRESETS[preset], noise=noise, seed=food_seed(food),
                     calibration=PROBE_CALIBRATIONS.get(preset), runs=runs)
    return float(out.details.get("cpu_fits", math.nan)), dict(out.estimates)


def time_fits(foods: list[Food], runs: list[ProbeRuns], preset: str, noise: float,
              repeats: int) -> tuple[np.ndarray, list[dict[str, float]], int]:
    """Fits timings [s] (repeats x foods, interleaved passes), each food's estimates and how
    many passes gave estimates other than the first pass's."""
    timings = np.full((repeats, len(foods)), math.nan)
    first: list[dict[str, float]] = []
    differing = 0
    for p in range(repeats):
        for j, (food, r) in enumerate(zip(foods, runs, strict=True)):
            timings[p, j], est = fit_once(food, r, preset, noise)
            if p == 0:
                first.append(est)
            elif not _close(est, first[j], 0.0):
                differing += 1
    return timings, first, differing


def committed_path(directory: Path, set_name: str, preset: str, noise: float) -> Path:
    """The harness's calibrated run of these settings in ``directory``."""
    return directory / f"{set_name}_{preset}_noise{noise:g}.json"


def _close(a: dict[str, float], b: dict[str, float], rtol: float) -> bool:
    """Estimates equal to a relative ``rtol`` (0: bit for bit), NaN equal to NaN."""
    return a.keys() == b.keys() and all(
        a[k] == b[k] or abs(a[k] - b[k]) <= rtol * abs(b[k])
        or (math.isnan(a[k]) and math.isnan(b[k])) for k in a)


def committed_mismatches(directory: Path, set_name: str, preset: str, noise: float,
                         foods: list[Food], estimates: list[dict[str, float]],
                         rtol: float = 0.0) -> tuple[int, list[int]]:
    """(foods compared, indices whose estimates differ by more than ``rtol``) against the
    harness's committed records of these foods."""
    path = committed_path(directory, set_name, preset, noise)
    by_index = {r["food"]["index"]: r for r in json.loads(path.read_text())["records"]}
    compared, differ = 0, []
    for food, est in zip(foods, estimates, strict=True):
        rec = by_index.get(food.index)
        if rec is None or "estimate" not in rec:
            continue
        compared += 1
        if not _close(est, {k: float(v) for k, v in rec["estimate"].items()}, rtol):
            differ.append(food.index)
    return compared, differ


def summarize(timings: np.ndarray, bar: float) -> dict[str, Any]:
    """Each food's median over the passes, and the figures over the foods [s]."""
    per_food = np.median(timings, axis=0)
    slowest = int(np.argmax(per_food))
    return {
        "median": float(np.median(per_food)),
        "p95": float(np.percentile(per_food, 95)),
        "max": float(per_food[slowest]),
        "slowest_position": slowest,
        "over_bar": int(np.sum(per_food > bar)),
        "raw_max": float(np.max(timings)),
        "raw_over_bar": int(np.sum(timings > bar)),
        "raw_count": int(timings.size),
    }


def _parse(argv: list[str] | None) -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--set", dest="set_name", choices=SETS, default="reporting")
    p.add_argument("--n", type=int, default=64, help="foods of the set (default 64)")
    p.add_argument("--preset", choices=sorted(PROBE_PRESETS), default="precise")
    p.add_argument("--noise", type=float, nargs="+", default=[0.0, 0.01],
                   help="sensor noise levels, each fitted on the same simulations")
    p.add_argument("--repeats", type=int, default=5, help="timings of each food's fits")
    p.add_argument("--workers", type=int, default=1, help="processes for the simulations")
    p.add_argument("--check-against", type=Path, default=None,
                   help="the harness's output folder: the estimates must be its records'")
    p.add_argument("--out", type=Path, default=None, help="JSON to write")
    args = p.parse_args(argv)
    for name, low in (("n", 1), ("repeats", 1), ("workers", 1)):
        if getattr(args, name) < low:
            p.error(f"--{name} must be >= {low}, got {getattr(args, name)}")
    for noise in args.noise:
        if not 0.0 <= noise <= 0.5:
            p.error(f"--noise must be in [0, 0.5], got {noise:g}")
    args.noise = list(dict.fromkeys(args.noise))  # each level once
    if args.check_against is not None:
        if not args.check_against.is_dir():
            p.error(f"--check-against: no folder {args.check_against}")
        for noise in args.noise:
            path = committed_path(args.check_against, args.set_name, args.preset, noise)
            if not path.exists():
                p.error(f"--check-against: no {path} (run the harness with these settings)")
    return args


def main(argv: list[str] | None = None) -> int:
    args = _parse(argv)
    stop_on_signals()
    try:
        return _run(args)
    except KeyboardInterrupt as exc:  # Ctrl-C, or SIGTERM / SIGHUP raised as one
        print(f"bench_fits: stopped ({exc.args[0] if exc.args else 'SIGINT'}) before every "
              "food was timed; nothing written (a figure needs every food)", file=sys.stderr)
        return stop_exit_code(exc)
    except WorkerLostError as exc:
        print(f"bench_fits: {exc}; nothing written", file=sys.stderr)
        return 1


def _run(args: argparse.Namespace) -> int:
    """Simulate, time the fits, write the JSON; 1 where an estimate did not reproduce."""
    info = meta()
    start = time.perf_counter()
    foods = foods_of(args.set_name, args.n)
    simulated = simulate(foods, args.preset, args.workers)
    runs = [r for r, _ in simulated]
    sim_cpu = np.array([c for _, c in simulated])
    result: dict[str, Any] = {
        "meta": info, "set": args.set_name, "preset": args.preset, "repeats": args.repeats,
        "foods": [f.index for f in foods], "bars_s": SPEED_BARS,
        "simulations_cpu_s": sim_cpu.tolist(), "fits": {}}
    print(f"simulations, CPU s a food: median {np.median(sim_cpu):.2f}, max "
          f"{sim_cpu.max():.2f} (food {foods[int(np.argmax(sim_cpu))].index}), "
          f"{int(np.sum(sim_cpu > SPEED_BARS['probes']))} of {len(foods)} over "
          f"{SPEED_BARS['probes']:g} s", flush=True)
    for noise in args.noise:
        timings, estimates, differing = time_fits(foods, runs, args.preset, noise,
                                                  args.repeats)
        entry = summarize(timings, SPEED_BARS["fits"])
        entry["slowest_food"] = foods[entry.pop("slowest_position")].index
        entry.update(passes_differing=differing, timings_s=timings.tolist())
        if args.check_against is not None:
            entry["committed_rtol"] = committed_rtol()
            entry["committed_compared"], entry["committed_differing"] = committed_mismatches(
                args.check_against, args.set_name, args.preset, noise, foods, estimates,
                entry["committed_rtol"])
        result["fits"][f"{noise:g}"] = entry
        print(_line(noise, entry, len(foods), args.repeats), flush=True)
    result["meta"]["wall_s"] = round(time.perf_counter() - start, 1)
    if args.out is not None:
        write_json(args.out, result)
        print(f"wrote {args.out}")
    bad = [e for e in result["fits"].values()
           if e["passes_differing"] or e.get("committed_differing")]
    return 1 if bad else 0


def _line(noise: float, e: dict[str, Any], n: int, repeats: int) -> str:
    check = ""
    if "committed_compared" in e:
        same = e["committed_compared"] - len(e["committed_differing"])
        check = (f"; estimates as committed on {same} of {e['committed_compared']} foods "
                 f"({kernels_note()})")
    return (f"fits, noise {noise:g}, CPU ms a food (median of {repeats}): median "
            f"{1e3 * e['median']:.1f}, 95th pct {1e3 * e['p95']:.1f}, max {1e3 * e['max']:.1f} "
            f"(food {e['slowest_food']}), {e['over_bar']} of {n} over "
            f"{1e3 * SPEED_BARS['fits']:g} ms; every timing: max {1e3 * e['raw_max']:.1f}, "
            f"{e['raw_over_bar']} of {e['raw_count']} over; passes differing from the first: "
            f"{e['passes_differing']}{check}")


if __name__ == "__main__":
    raise SystemExit(main())
