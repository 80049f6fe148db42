"""How a diced fetch's outcome depends on the physics step: agreement with a finer step.

A diced fetch is chaotic (which column the blades grip, which piece slips out), so a coarser
step is judged by outcomes, not traces: for each seeded mix, each piece's fetched-or-not is
compared with the run at the finest step, the reference.  Also printed per step: mixes whose
every piece agrees, mixes with a crushed piece (LE > 1: a one-cell flex inverted), runs in
which MuJoCo warned (an under-converged effective-metric solve, say), the mean
fetch rate and the median real-time factor (with ``--workers`` > 1 the runs share the
machine: read the speed from ``bench_simulator.py``).

How much agreement to expect at all: with ``--twins`` every step is also run on the same mix
with each piece moved 1 nm along x (a seeded sign per piece), a change far below anything
physical.  A twin's agreement with its own step's run is that step's chaos floor: what the
contact events' sensitivity alone reorders, with no change to the physics.

``--impratios`` pairs each step with a friction impratio (the scene's default where omitted:
1000 for one piece, 100 for several, ``fetch_env.scene``), so the same table judges impratio:
``--steps 0.0025,0.005,0.005 --impratios 1000,1000,100`` compares the multi-piece default
(5 ms, 100) with 5 ms at 1000 against a 2.5 ms reference at 1000.  Each run's speed is also
summed: total simulated time over total wall time (with ``--workers`` > 1, relative only).

``--hold-scales`` pairs each step with a quasi-static hold scale (the env's
``fetch_hold_scale``; 1, real time, where omitted), so ``--steps 0.005,0.005 --hold-scales
1,5 --twins`` judges the fetch's holds stepped quasi-statically against the real-time fetch
and its chaos floor (docs/validation/quasi-static-holds.md).  ``--clamp-speeds`` likewise
pairs each step with the env's ``fetch_clamp_speed`` (0, every clamp in real time, where
omitted).

Run: python benchmarks/bench_step_size.py [--seeds 20] [--workers 2] [--twins] [--json FILE]
       [--steps 0.0025,0.005,0.01] [--impratios 1000,1000,100] [--hold-scales 1,1,5]
       [--clamp-speeds 0,0,0.2]
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import platform
import statistics
from collections.abc import Sequence
from concurrent.futures import ProcessPoolExecutor

import mujoco
import numpy as np

from fetch_env.controller import (
    FetchAction,
    FetchSimulator,
    fetch_hold_time_scale,
    make_profile,
)
from fetch_env.layouts import Piece, diced_mix

CRUSHED_LOG_STRAIN = 1.0  # above it a piece's one-cell flex has inverted (README, "Crushed")
TWIN_SHIFT = 1e-9  # [m] how far a twin's pieces are moved: physically nothing


def twin_of(pieces: Sequence[Piece], signs: Sequence[float]) -> tuple[Piece, ...]:
    """A scene's twin: every piece moved ``TWIN_SHIFT`` along x, by ``signs`` (+-1, one a
    piece): a change of nothing physical, whose effect on an outcome is the chaos floor."""
    return tuple(dataclasses.replace(p, x=p.x + s * TWIN_SHIFT)
                 for p, s in zip(pieces, signs, strict=True))


def run_mix(seed: int, steps: tuple[float, ...], theta_d: float, twins: bool = False,
            impratios: tuple[float | None, ...] | None = None,
            hold_scales: tuple[float, ...] | None = None,
            clamp_speeds: tuple[float, ...] | None = None, omega: float = 0.1) -> list[dict]:
    """One seeded diced mix (6-12 pieces), fetched once at each step with its impratio
    (None: the scene's default), hold scale (1: real time) and clamp speed (0: real time),
    then, with ``twins``, once more at each with every piece moved by ``TWIN_SHIFT``."""
    rng = np.random.default_rng(seed)
    pieces = diced_mix(rng)
    signs = rng.choice([-1.0, 1.0], size=len(pieces))
    moved = twin_of(pieces, signs)
    configs = list(zip(steps, impratios or (None,) * len(steps),
                       hold_scales or (1.0,) * len(steps),
                       clamp_speeds or (0.0,) * len(steps), strict=True))
    out = []
    for (dt, imp, k, clamp), layout in ([(c, pieces) for c in configs]
                                        + [(c, moved) for c in configs if twins]):
        scale = fetch_hold_time_scale(k, clamp)
        action = FetchAction(theta_d=theta_d, omega=omega)
        r = FetchSimulator(layout, timestep=dt, impratio=imp).run("fetch", action,
                                                                  time_scale=scale)
        physical = float(make_profile("fetch", action, dt, scale).step_time.sum())
        out.append({"fetched": [bool(p["fetched"]) for p in r.pieces],
                    "log_strain": max(max(p["max_log_strain_clamp"], p["max_log_strain_lift"])
                                      for p in r.pieces),
                    "fetch_rate": r.fetch_rate,
                    "warned": bool(r.extra["mujoco_warnings"]),
                    "realtime": physical / r.wall_time,
                    "simulated": physical, "wall": r.wall_time})
    return out


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--seeds", type=int, default=20, help="number of mixes (default 20)")
    p.add_argument("--first-seed", type=int, default=1)
    p.add_argument("--theta-d", type=float, default=0.085, help="clamp angle [rad]")
    p.add_argument("--omega", type=float, default=0.1, help="clamp speed [rad/s]")
    p.add_argument("--steps", type=lambda s: tuple(float(x) for x in s.split(",")),
                   default=(0.0025, 0.005, 0.01), help="physics steps [s]; the first is the "
                   "reference (default 0.0025,0.005,0.01)")
    p.add_argument("--impratios", type=lambda s: tuple(float(x) for x in s.split(",")),
                   default=None, help="friction impratio of each step's runs, as many as "
                   "--steps (default: the scene's, 1000 for one piece and 100 for several)")
    p.add_argument("--hold-scales", type=lambda s: tuple(float(x) for x in s.split(",")),
                   default=None, help="quasi-static hold scale of each step's runs, as many "
                   "as --steps, each in [1, 20] (default: 1, real time)")
    p.add_argument("--clamp-speeds", type=lambda s: tuple(float(x) for x in s.split(",")),
                   default=None, help="quasi-static clamp speed of each step's runs, as many "
                   "as --steps, each 0 or in [0.05, 0.4] rad/s (default: 0, real time)")
    p.add_argument("--workers", type=int, default=1)
    p.add_argument("--twins", action="store_true",
                   help="also run each step with the pieces moved 1 nm (the chaos floor)")
    p.add_argument("--json", metavar="FILE", help="also write every run's outcome here")
    args = p.parse_args()
    if args.seeds < 1 or args.workers < 1 or len(args.steps) < 2:
        p.error("--seeds and --workers must be >= 1 and --steps must name at least two steps")
    if not 1e-3 <= args.omega <= 2.0:  # FetchAction's range (NaN fails too)
        p.error(f"--omega {args.omega} is not in [0.001, 2] rad/s")
    if args.impratios is not None and len(args.impratios) != len(args.steps):
        p.error(f"--impratios names {len(args.impratios)} values for {len(args.steps)} steps")
    bad = [x for x in args.impratios or () if not 1 <= x <= 1e4]  # (NaN fails too)
    if bad:
        p.error(f"--impratios: {bad[0]} is not in [1, 1e4]")
    if args.hold_scales is not None and len(args.hold_scales) != len(args.steps):
        p.error(f"--hold-scales names {len(args.hold_scales)} values for {len(args.steps)} steps")
    bad = [x for x in args.hold_scales or () if not 1 <= x <= 20]
    if bad:
        p.error(f"--hold-scales: {bad[0]} is not in [1, 20]")
    if args.clamp_speeds is not None and len(args.clamp_speeds) != len(args.steps):
        p.error(f"--clamp-speeds names {len(args.clamp_speeds)} values for "
                f"{len(args.steps)} steps")
    bad = [x for x in args.clamp_speeds or () if not (x == 0 or 0.05 <= x <= 0.4)]
    if bad:
        p.error(f"--clamp-speeds: {bad[0]} is not 0 or in [0.05, 0.4]")
    if args.json and not os.path.isdir(os.path.dirname(os.path.abspath(args.json))):
        p.error(f"--json {args.json}: no such directory")
    seeds = range(args.first_seed, args.first_seed + args.seeds)
    print(f"machine: {platform.machine()} {platform.processor()}, {os.cpu_count()} cores, "
          f"python {platform.python_version()}, mujoco {mujoco.__version__}; "
          f"{args.seeds} diced mixes (seeds {seeds[0]}-{seeds[-1]}), theta_d {args.theta_d} rad "
          f"at {args.omega} rad/s, "
          f"{args.workers} worker(s)")
    with ProcessPoolExecutor(args.workers) as pool:
        runs = list(pool.map(run_mix, seeds, [args.steps] * len(seeds),
                             [args.theta_d] * len(seeds), [args.twins] * len(seeds),
                             [args.impratios] * len(seeds), [args.hold_scales] * len(seeds),
                             [args.clamp_speeds] * len(seeds), [args.omega] * len(seeds)))
    n_pieces = sum(len(r[0]["fetched"]) for r in runs)

    def rate_shift(k: int, ref: int) -> str:
        """Mean fetch-rate difference over the mixes, paired, with its standard error."""
        diff = [r[k]["fetch_rate"] - r[ref]["fetch_rate"] for r in runs]
        se = statistics.stdev(diff) / len(diff) ** 0.5 if len(diff) > 1 else float("nan")
        return f"fetch rate {statistics.mean(diff):+.3f} +- {se:.3f}"

    def agreement(k: int, ref: int) -> str:
        agree = sum(sum(a == b for a, b in zip(r[ref]["fetched"], r[k]["fetched"], strict=True))
                    for r in runs)
        whole = sum(r[ref]["fetched"] == r[k]["fetched"] for r in runs)
        return f"{agree}/{n_pieces} ({agree / n_pieces:.1%}), whole mixes {whole:2d}/{len(runs)}"

    n = len(args.steps)
    labels = [f"{dt * 1000:5.2f} ms" + ("" if imp is None else f" at impratio {imp:g}")
              + ("" if k == 1 else f", holds x{k:g}")
              + ("" if not c else f", clamps at {c:g} rad/s")
              for dt, imp, k, c in zip(args.steps, args.impratios or (None,) * n,
                                       args.hold_scales or (1.0,) * n,
                                       args.clamp_speeds or (0.0,) * n, strict=True)]
    twin_label = f"pieces moved {TWIN_SHIFT * 1e9:g} nm"
    labels += [f"{label}, {twin_label}" for label in labels] if args.twins else []
    for k, label in enumerate(labels):
        crushed = sum(r[k]["log_strain"] > CRUSHED_LOG_STRAIN for r in runs)
        warned = sum(r[k]["warned"] for r in runs)
        vs_ref = ("reference" if k == 0 else
                  f"agree with reference {agreement(k, 0)}, {rate_shift(k, 0)}")
        print(f"step {label}: {vs_ref}; crushed {crushed}, MuJoCo warnings {warned}, mean "
              f"fetch rate {statistics.mean(r[k]['fetch_rate'] for r in runs):.3f}, median "
              f"{statistics.median(r[k]['realtime'] for r in runs):.2f}x real time, in all "
              f"{sum(r[k]['simulated'] for r in runs) / sum(r[k]['wall'] for r in runs):.2f}x")
        if k >= n:  # a twin: its agreement with its own step's run is the chaos floor
            print(f"    chaos floor (with the unmoved run at the same step): {agreement(k, k - n)}"
                  f", {rate_shift(k, k - n)}")
    if args.json:
        with open(args.json, "w") as f:
            json.dump({"seeds": list(seeds), "theta_d": args.theta_d, "omega": args.omega,
                       "runs": labels,
                       "mixes": runs}, f)


if __name__ == "__main__":
    main()
