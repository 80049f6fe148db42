"""Benchmark of the viscoelastic estimators (a script, not a test).

Times the full least-squares fit (target < 50 ms) and the study's three-step method (target
< 5 ms) on a 10 s trace at 100 Hz (1 % of M_peak white noise), the friction estimator on a 12 s
slip trace, and prints the machine.

    python benchmarks/bench_estimators.py [--repeats N]
"""

from __future__ import annotations

import argparse
import os
import platform
import statistics
import sys
import time
from pathlib import Path

import numpy as np

# Benchmark this checkout's package, not whatever copy happens to be installed.
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from estimators.friction import estimate_friction
from estimators.relaxation import estimate_full_fit, estimate_three_step
from estimators.sls import ClampGeometry, SLSParams, clamp_angle, moment_trace


def _trace(seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    geom = ClampGeometry(L=0.05, theta_0=0.17)
    params = SLSParams.from_prony(2000.0, 0.425, 3.667)
    omega, theta_d = 0.03, 0.0244
    t = np.arange(0.0, 10.0, 0.01)  # 1000 samples: clamp to t_d = 0.81 s, then hold
    theta = clamp_angle(t, theta_d, omega)
    m = moment_trace(t, params, geom, 0.02, theta_d, omega)
    rng = np.random.default_rng(seed)
    return t, theta, m + 0.01 * m.max() * rng.standard_normal(m.size)


def _median_ms(fn, traces, geom) -> float:
    times = []
    for t, theta, m in traces:
        t0 = time.perf_counter()
        fn(t, theta, m, geom)
        times.append(time.perf_counter() - t0)
    return 1e3 * statistics.median(times)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=50)
    args = ap.parse_args()
    geom = ClampGeometry(L=0.05, theta_0=0.17)
    traces = [_trace(seed) for seed in range(args.repeats)]
    for fn in (estimate_full_fit, estimate_three_step):  # warm-up (imports, caches)
        fn(*traces[0], geom)
    full = _median_ms(estimate_full_fit, traces, geom)
    three = _median_ms(estimate_three_step, traces, geom)
    print(
        f"machine: {platform.processor() or platform.machine()}, {os.cpu_count()} CPUs, "
        f"{platform.system()} {platform.release()}, Python {platform.python_version()}, "
        f"numpy {np.__version__}"
    )
    print(f"trace: 10 s at 100 Hz (1000 samples), {args.repeats} noisy repeats")
    print(f"full fit   median {full:7.2f} ms  (target < 50 ms) {'OK' if full < 50 else 'SLOW'}")
    print(f"three-step median {three:7.2f} ms  (target <  5 ms) {'OK' if three < 5 else 'SLOW'}")
    # Friction: a 12 s slip trace at 100 Hz (clamp, hold, 10 s slide), 1 % force noise.
    t = np.arange(0.0, 12.0, 0.01)
    n = np.where(t > 0.6, 4.0 * np.exp(-t / 10.0), 0.0)
    rng = np.random.default_rng(0)
    tang = np.where(t > 1.5, 0.3, 0.2) * n + 0.04 * rng.standard_normal(t.size)
    times = []
    for _ in range(args.repeats):
        t0 = time.perf_counter()
        estimate_friction(t, n, np.abs(tang), n, np.abs(tang))
        times.append(time.perf_counter() - t0)
    print(f"friction   median {1e3 * statistics.median(times):7.2f} ms  (12 s slip at 100 Hz)")


if __name__ == "__main__":
    main()
