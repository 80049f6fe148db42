"""Speed, for the README: the simulator's real-time factor and the environments' episodes/s.

Uses ``benchmarks/bench_simulator.py``'s timing (medians over interleaved runs, one core) on
the single 15 mm soft cube's fetch and on 9-piece diced mixes (seeds 1-5 at 0.085 rad, the
median of one run each: a diced fetch's cost follows its chaotic trajectory), and
``benchmarks/bench_env.py``'s one-core loop (random actions, default env settings, model
estimator, reset seeds 1000 + i) on every id.  What the opt-in quasi-static settings save
is measured paired over 40 scenes an id by ``benchmarks/bench_quasi_static.py``, which the
README's table reads too: over a few episodes the ratio moves by tenths, as a chaotic fetch
simulated another way may end another way and cost another time.  Writes JSON with the
machine and the command for ``scripts/make_readme_tables.py``.  Run it on an otherwise idle
machine: the load average at the start and at the end is recorded.

    python benchmarks/speed_summary.py --episodes 8 --out docs/data/readme_speed.json
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import fetch_env
from benchmarks.bench_env import one_core
from benchmarks.bench_simulator import bench
from benchmarks.readme_meta import meta, write_json
from fetch_env.controller import FetchAction
from fetch_env.layouts import diced_mix, single_block


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--episodes", type=int, default=8, help="episodes per env id (default 8)")
    p.add_argument("--out", type=Path, default=Path("docs/data/readme_speed.json"))
    args = p.parse_args()
    info = meta()
    start = time.perf_counter()
    cube = bench("single 15 mm soft cube", single_block(), FetchAction())
    diced = [bench(f"9-piece diced mix, seed {seed}",
                   diced_mix(np.random.default_rng(seed), n_pieces=9),
                   FetchAction(theta_d=0.085), repeats=1) for seed in range(1, 6)]
    simulator = {
        "cube": {k: cube[k] for k in ("realtime", "steps_per_s", "ratio", "ratio_in_run")},
        "diced_median": {k: statistics.median(r[k] for r in diced)
                         for k in ("realtime", "steps_per_s", "ratio", "ratio_in_run")},
        "diced_seeds": [1, 2, 3, 4, 5],
    }
    envs = {}
    for env_id in fetch_env.ENV_IDS:
        r = one_core(env_id, args.episodes, estimator="model")
        envs[env_id] = {k: r[k] for k in ("eps", "eps_cpu", "probe_share", "errors")}
        print(f"{env_id}: {r['eps']:.2f} episodes/s, probes {r['probe_share']:.0%}",
              flush=True)
    info["wall_s"] = round(time.perf_counter() - start, 1)
    info["load_average_at_end"] = round(os.getloadavg()[0], 2)
    write_json(args.out, {"meta": info, "episodes": args.episodes, "simulator": simulator,
                          "envs": envs})
    print(f"wrote {args.out} in {info['wall_s']:.0f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
