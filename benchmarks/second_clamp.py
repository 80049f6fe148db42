"""A second and third clamp as a check: does their disagreement flag the probe's misses?

The ``reliable`` flag must be False on every food whose g1, tau1 or mu error exceeds 5 %,
and True on most foods measured within 2 %.  The calibrated error model's per-food sd does
not separate the two (``docs/estimator_validation.md``): what the calibration leaves is a
per-food bias that each trace shows only roughly.  A second, independent reading is the
other way an instrument checks itself: clamp the same food again at another squeeze or
speed, calibrate each clamp on the tuning foods as the shipped probe is, and read the
spread of their calibrated estimates.  Where the bias depends on the clamp, the readings
disagree on the foods they miss.

This script measures that on the tuning foods only (``TUNING_SEED``; the reporting foods
stay untouched): the ``measure`` probe, and the same probe at strain 0.10 (instead of
0.06), at omega 0.3 rad/s (instead of 0.1) and with 30 and 40 s holds (instead of 20 s:
whether a longer look at the relaxation helps one clamp), each uncalibrated, then each
calibrated by 8-fold cross-validation (``validate_estimators.cross_validate``: every food's
estimate from a calibration fitted without it).  It reports, for each probe alone and every
combination of the first three, the median and 95th percentile of |error| of the mean of
their calibrated log-estimates of g1 and tau1, the rank correlation of that error with the
clamps' spread, and the best flag the spread can give: the share of foods within 2 % that a
spread threshold calls reliable while calling no 5 % miss reliable.

    python benchmarks/second_clamp.py --n 256 --workers 2 \\
        --base docs/data/validation/tuning_measure_uncal_noise0.json

Each clamp's records stream to ``--work`` (a stopped run continues from them); the summary
is written to ``--out`` (default ``docs/data/validation/second_clamp.json``).
"""

from __future__ import annotations

import argparse
import dataclasses
import hashlib
import itertools
import json
import math
import sys
from pathlib import Path
from typing import Any

import numpy as np
from scipy.stats import spearmanr

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))

import validate_estimators as ve

from fetch_env.food_space import TUNING_SEED, Food, sample_foods
from fetch_env.probes import PROBE_PRESETS, ProbeConfig
from fetch_env.scene import Geometry

BASE = PROBE_PRESETS["measure"]
VARIANTS: dict[str, ProbeConfig] = {
    "strain 0.10": dataclasses.replace(BASE, strain=0.10),
    "omega 0.3": dataclasses.replace(BASE, omega=0.3),
    "hold 30 s": dataclasses.replace(BASE, hold=30.0),
    "hold 40 s": dataclasses.replace(BASE, hold=40.0),
}
# the variants combined with the measure probe (the longer holds are reported alone: they are
# the same clamp, held longer)
COMBINED: tuple[str, ...] = ("measure", "strain 0.10", "omega 0.3")
TARGETS = ("g1", "tau1")


def run_variant(name: str, config: ProbeConfig, foods: list[Food], work: Path,
                workers: int, geometry: Geometry | None = None
                ) -> tuple[list[dict[str, Any]], str]:
    """Uncalibrated records of one clamp (by ``config``, with ``geometry`` where given) on
    ``foods``, streamed to ``work`` and resumed by the harness's own runner; and why it
    stopped ("" when every food finished)."""
    # the settings name the file, so that records of other settings (an older preset, another
    # geometry) are never resumed into this run
    settings = json.dumps([dataclasses.asdict(config),
                           None if geometry is None else dataclasses.asdict(geometry)],
                          sort_keys=True)
    tag = hashlib.sha256(settings.encode()).hexdigest()[:10]
    path = work / f"{name.replace(' ', '_')}-{tag}.jsonl"
    done = ve._done_indices(path)
    records = list(done.values())
    todo = [f for f in foods if f.index not in done]
    run = argparse.Namespace(preset="measure", noise=0.0, workers=workers)
    stopped = ve._run_foods(todo, run, False, path, records, config, geometry)
    return records, stopped


def _log_errors(held: dict[str, dict[int, dict[str, Any]]], clamps: tuple[str, ...],
                index: list[int], target: str) -> np.ndarray:
    """log(estimate / truth) per clamp (rows) and food (columns); NaN where one failed."""
    out = np.full((len(clamps), len(index)), math.nan)
    for i, c in enumerate(clamps):
        for j, k in enumerate(index):
            r = held[c].get(k)
            v = r["estimate"][target] if r else math.nan
            if r and math.isfinite(v) and v > 0:
                out[i, j] = math.log(v / r["truth"][target])
    return out


def combination(held: dict[str, dict[int, dict[str, Any]]], clamps: tuple[str, ...],
                index: list[int]) -> dict[str, Any]:
    """Accuracy of the clamps' mean, and how well their spread flags a miss."""
    errs = {t: _log_errors(held, clamps, index, t) for t in TARGETS}
    ok = np.all([np.isfinite(e).all(axis=0) for e in errs.values()], axis=0)
    out: dict[str, Any] = {"clamps": list(clamps), "foods": int(ok.sum())}
    worst = np.zeros(int(ok.sum()))
    spread = np.zeros(int(ok.sum()))
    for t, e in errs.items():
        mean = np.abs(e[:, ok].mean(axis=0))
        out[t] = {"median": float(np.median(mean)), "p95": float(np.percentile(mean, 95))}
        worst = np.maximum(worst, mean)
        if len(clamps) > 1:
            s = np.ptp(e[:, ok], axis=0)
            ranked = np.ptp(s) > 0 and np.ptp(mean) > 0  # else no rank correlation exists
            out[t]["spearman_error_spread"] = float(spearmanr(mean, s)[0]) if ranked else math.nan
            spread = np.maximum(spread, s)
    if len(clamps) > 1:
        bad, good = spread[worst > math.log(1.05)], spread[worst < math.log(1.02)]
        out["flag"] = {"n_over_5pct": int(bad.size), "n_under_2pct": int(good.size),
                       "under_2pct_passed": int(np.sum(good < bad.min())) if bad.size
                       else int(good.size),
                       "spread_threshold": float(bad.min()) if bad.size else math.inf}
    return out


def _signed_median(records: list[dict[str, Any]], target: str) -> float:
    """Median signed relative error of a probe's own (uncalibrated) estimates: its bias."""
    errs = [r["error"][target] for r in records if "error" in r]
    return float(np.nanmedian(errs)) if errs else math.nan


def table(results: list[dict[str, Any]]) -> str:
    rows = ["| clamps | g1 median / 95th | tau1 median / 95th | spread vs error (g1, tau1) "
            "| within 2 % called reliable, no 5 % miss |", "|---|---|---|---|---|"]
    for r in results:
        acc = [f"{100 * r[t]['median']:.2f} / {100 * r[t]['p95']:.1f} %" for t in TARGETS]
        if "flag" in r:
            f = r["flag"]
            rho = ", ".join(f"{r[t]['spearman_error_spread']:.2f}" for t in TARGETS)
            flag = f"{f['under_2pct_passed']} of {f['n_under_2pct']}"
        else:
            rho = flag = "-"
        rows.append(f"| {' + '.join(r['clamps'])} | {acc[0]} | {acc[1]} | {rho} | {flag} |")
    return "\n".join(rows)


def parse_tuning_args(description: str, name: str, argv: list[str] | None
                      ) -> tuple[argparse.Namespace, list[dict[str, Any]], list[Food]]:
    """The command line of a script that reprobes the tuning foods (``--n``, ``--workers``,
    ``--base``, ``--work``, ``--out``), checked: the parsed arguments, the base run's
    records and the foods.  Exits with argparse's one-line error on a bad value or a base
    that is not an uncalibrated, noiseless tuning run of the measure preset."""
    p = argparse.ArgumentParser(description=description)
    p.add_argument("--n", type=int, default=256, help="tuning foods (default 256)")
    p.add_argument("--workers", type=int, default=1)
    p.add_argument("--base", type=Path, required=True, metavar="JSON",
                   help="the measure probe's uncalibrated tuning run (validate_estimators.py "
                   "--set tuning --no-calibration --noise 0) on the same foods")
    p.add_argument("--work", type=Path, default=Path(f"out/{name}"))
    p.add_argument("--out", type=Path, default=Path(f"docs/data/validation/{name}.json"))
    args = p.parse_args(argv)
    if not 16 <= args.n <= 4096 or args.workers < 1:
        p.error(f"--n {args.n} must be in [16, 4096] and --workers {args.workers} >= 1")
    base = json.loads(args.base.read_text())
    if (base["meta"]["set"], base["meta"]["n"], base["meta"]["noise"]) != ("tuning", args.n, 0) \
            or base["meta"].get("calibration") is not None or base["meta"]["preset"] != "measure":
        p.error(f"--base {args.base}: not an uncalibrated, noiseless tuning run of the "
                f"measure preset on {args.n} foods")
    # a setting added since the base run was made is missing from its meta: it ran with that
    # setting's default, which is what ProbeConfig fills in
    recorded = base["meta"].get("probe_config")
    try:
        same = isinstance(recorded, dict) and ProbeConfig(**recorded) == BASE
    except (TypeError, ValueError):  # a setting today's ProbeConfig does not have or refuses
        same = False
    if not same:
        p.error(f"--base {args.base}: made with other measure-probe settings than today's "
                f"(meta.probe_config {base['meta'].get('probe_config')}); rerun it")
    args.work.mkdir(parents=True, exist_ok=True)
    return args, base["records"], sample_foods(args.n, TUNING_SEED)


def main(argv: list[str] | None = None) -> int:
    args, base, foods = parse_tuning_args(__doc__.split("\n\n")[0], "second_clamp", argv)
    runs = {"measure": base}
    for name, config in VARIANTS.items():
        runs[name], stopped = run_variant(name, config, foods, args.work, args.workers)
        if stopped:
            print(f"second_clamp: {stopped}; {len(runs[name])} of {args.n} foods of "
                  f"{name!r} kept in {args.work} (rerun the same command to finish)",
                  file=sys.stderr)
            return 130 if "interrupted" in stopped else 1
    # in food order, so that the fits' sums, and so their last bits, do not depend on the
    # order in which the workers finished
    runs = {k: sorted(v, key=lambda r: int(r["food"]["index"])) for k, v in runs.items()}
    held = {name: {int(r["food"]["index"]): r
                   for r in ve.cross_validate(recs, [recs])[0]["records"]}
            for name, recs in runs.items()}
    index = [f.index for f in foods]
    results = [combination(held, (name,), index) | {"tau1_uncalibrated_signed_median":
                                                     _signed_median(recs, "tau1")}
               for name, recs in runs.items()]
    results += [combination(held, clamps, index) for n in range(2, len(COMBINED) + 1)
                for clamps in itertools.combinations(COMBINED, n)]
    summary = {"meta": {"set": "tuning", "seed": TUNING_SEED, "n": args.n,
                        "variants": {k: dataclasses.asdict(v) for k, v in VARIANTS.items()},
                        "command": "python benchmarks/second_clamp.py "
                        + " ".join(argv or sys.argv[1:])},
               "results": results}
    ve._write_atomic(args.out, json.dumps(summary, indent=1, default=float) + "\n")
    print(table(results))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
