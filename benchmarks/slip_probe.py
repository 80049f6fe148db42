"""How the slip probe's clamp reads mu: its gap, squeeze and step against the truth, on the
tuning foods only (``TUNING_SEED``), uncalibrated, with and without 1 % sensor noise.

The blades close by turning about the hinge, so at the slip probe's clamp angle their faces
lean in by that angle while a cube's sides stand upright.  A blade tip's edge then presses
into the side, and the normals of its contacts (the side's) lean from the blade's face by
the clamp angle: in the blade's frame their push reads as friction, ``mu + angle (1 +
mu^2)``.  A blade that starts closer to the food (``ProbeConfig.slip_gap``) and squeezes it
less (``slip_strain``) closes by a smaller angle.  Each variant here is the ``measure``
preset's slip probe with some of those settings changed; the last three are the
``precise`` preset's, with one slide, with three (0.3, 0.45 and 0.2 s) and with its five
(and 0.675 and 0.133 s, ``slip_repeats``), whose median is mu.  Each reads mu with the two
half-spoons' envelopes (``per_blade``) and, where sensor noise is added, also less what
the noise adds (``per_blade_denoised``) and refined to the level the ratio slips at
(``per_blade_slipping``), and that level less the bias the noise leaves in it,
extrapolated away (``per_blade_simex``, ``estimators.slip_simex``: the ``precise``
preset's).

    python benchmarks/slip_probe.py --n 512 --workers 2

Each variant's per-food errors stream to ``--work`` (a stopped run continues from them when
the same command is run again).  Prints a table (median, 90th and 95th percentile and
maximum of |mu error|, mean error, foods past 1.4 %) and writes it with the settings to
``--out`` (default ``docs/data/validation/slip_probe.json``).
"""

from __future__ import annotations

import argparse
import dataclasses
import hashlib
import json
import sys
import warnings
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))

import validate_estimators as ve

from estimators import EstimationError
from fetch_env.errors import ParameterClippedWarning
from fetch_env.food_space import TUNING_SEED, Food, sample_foods
from fetch_env.probes import PROBE_PRESETS, ProbeConfig, estimate_mu, slide_times, slip_run

MEASURE = PROBE_PRESETS["measure"]
PRECISE = PROBE_PRESETS["precise"]
GAP = PRECISE.slip_gap
VARIANTS: dict[str, ProbeConfig] = {
    "measure (gap 1 mm, squeeze 0.1, 10 ms)": MEASURE,
    "gap 0.1 mm, squeeze 0.1": dataclasses.replace(MEASURE, slip_gap=GAP),
    "gap 0.1 mm, squeeze 0.05": dataclasses.replace(MEASURE, slip_gap=GAP, slip_strain=0.05),
    "gap 0.1 mm, squeeze 0.03": dataclasses.replace(MEASURE, slip_gap=GAP, slip_strain=0.03),
    "gap 0.1 mm, squeeze 0.03, 5 ms": dataclasses.replace(
        MEASURE, slip_gap=GAP, slip_strain=0.03, slip_timestep=0.005),
    "gap 0.1 mm, squeeze 0.03, 2.5 ms": dataclasses.replace(PRECISE, slip_repeats=1),
    "gap 0.1 mm, squeeze 0.03, 2.5 ms, median of 3 slides": dataclasses.replace(
        PRECISE, slip_repeats=3),
    "precise (gap 0.1 mm, squeeze 0.03, 2.5 ms, median of 5 slides)": PRECISE,
}
NOISE = 0.01
# each food's readings of mu: the key of its error and the table's label
READINGS = {"noise0": "no noise", "noise_per_blade": "1 % noise",
            "noise_denoised": "1 % noise, denoised",
            "noise_slipping": "1 % noise, slipping level",
            "noise_simex": "1 % noise, slipping level less its noise bias"}


def food_errors(food: Food, config: ProbeConfig) -> dict[str, Any]:
    """mu's relative error on ``food`` (a record naming it by index): without noise, and
    with ``NOISE`` read per blade, per blade less the noise, at the slipping level and at
    that level less its noise bias (noise
    drawn from the food's index, slide after slide), the median over ``config``'s slides;
    NaN where a slide gave no estimate."""
    warnings.simplefilter("ignore", ParameterClippedWarning)
    runs = [slip_run(food.piece(), dataclasses.replace(config, slide_time=t))
            for t in slide_times(config)]
    out: dict[str, Any] = {"food": {"index": food.index}}
    for key, noise, envelope in (("noise0", 0.0, "per_blade"),
                                 ("noise_per_blade", NOISE, "per_blade"),
                                 ("noise_denoised", NOISE, "per_blade_denoised"),
                                 ("noise_slipping", NOISE, "per_blade_slipping"),
                                 ("noise_simex", NOISE, "per_blade_simex")):
        rng = np.random.default_rng(food.index)
        try:
            mus = [estimate_mu(run, noise, rng, envelope=envelope)[0] for run in runs]
            out[key] = float(np.median(mus)) / food.mu - 1
        except EstimationError:
            out[key] = float("nan")
    return out


def run_variant(name: str, config: ProbeConfig, foods: list[Food], work: Path, workers: int
                ) -> tuple[list[dict[str, Any]], str]:
    """The records of ``config``'s slip probe on ``foods``, streamed to a file in ``work``
    named by the settings (records of other settings are never resumed into it) and resumed
    from it; and why it stopped ("" when every food finished)."""
    # the readings are part of the tag: records without one of them are never resumed
    settings = json.dumps([dataclasses.asdict(config), sorted(READINGS)], sort_keys=True)
    tag = hashlib.sha256(settings.encode()).hexdigest()[:10]
    path = work / f"{name.split(' (')[0].replace(' ', '_').replace(',', '')}-{tag}.jsonl"
    done = ve._done_indices(path)
    records = list(done.values())
    tasks = [(f, config) for f in foods if f.index not in done]
    stopped = ve.run_streamed(food_errors, tasks, workers, path, records)
    return records, stopped


def summarise(errors: list[float]) -> dict[str, float]:
    """Median, 90th and 95th percentile and max of |error|, mean error, foods past 1.4 % and
    foods without an estimate."""
    e = np.array(errors)
    ok = e[np.isfinite(e)]
    a = np.abs(ok)
    return {"median": float(np.median(a)), "p90": float(np.percentile(a, 90)),
            "p95": float(np.percentile(a, 95)), "max": float(a.max()),
            "mean": float(ok.mean()), "past_1.4%": int((a > 0.014).sum()),
            "failed": int(e.size - ok.size)}


def table(results: dict[str, dict[str, dict[str, float]]]) -> str:
    """The summary as a Markdown table, one row a variant and reading."""
    rows = ["| slip probe | reading | median / 90th / 95th / max | mean | past 1.4 % |",
            "|---|---|---|---|---|"]
    for name, by_reading in results.items():
        for key, label in READINGS.items():
            s = by_reading[key]
            rows.append(f"| {name} | {label} | {100 * s['median']:.2f} / {100 * s['p90']:.1f}"
                        f" / {100 * s['p95']:.1f} / {100 * s['max']:.0f} % | "
                        f"{100 * s['mean']:+.2f} % | {s['past_1.4%']} |")
    return "\n".join(rows)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--n", type=int, default=512, help="tuning foods (default 512)")
    p.add_argument("--workers", type=int, default=1)
    p.add_argument("--work", type=Path, default=Path("out/slip_probe"))
    p.add_argument("--out", type=Path, default=Path("docs/data/validation/slip_probe.json"))
    args = p.parse_args(argv)
    if not 16 <= args.n <= 4096 or args.workers < 1:
        p.error(f"--n {args.n} must be in [16, 4096] and --workers {args.workers} >= 1")
    foods = sample_foods(args.n, TUNING_SEED)
    args.work.mkdir(parents=True, exist_ok=True)
    results: dict[str, dict[str, dict[str, float]]] = {}
    for name, config in VARIANTS.items():
        records, stopped = run_variant(name, config, foods, args.work, args.workers)
        if stopped:
            print(f"slip_probe: {stopped}; {len(records)} of {args.n} foods of {name!r} kept "
                  f"in {args.work} (rerun the same command to finish)", file=sys.stderr)
            return ve.stopped_exit_code(stopped)
        index = {f.index for f in foods}
        mine = sorted((r for r in records if r["food"]["index"] in index),
                      key=lambda r: r["food"]["index"])
        results[name] = {key: summarise([r[key] for r in mine]) for key in READINGS}
        print(f"{name}: done", file=sys.stderr, flush=True)
    summary: dict[str, Any] = {
        "meta": {"set": "tuning", "seed": TUNING_SEED, "n": args.n, "noise": NOISE,
                 "variants": {k: dataclasses.asdict(v) for k, v in VARIANTS.items()},
                 "command": "python benchmarks/slip_probe.py " + " ".join(argv or sys.argv[1:])},
        "results": results}
    ve._write_atomic(args.out, json.dumps(summary, indent=1) + "\n")
    print(table(results))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
