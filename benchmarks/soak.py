"""Soak: many episodes of each env id in one process, watching memory and episode time.

Run: nice -n 10 python benchmarks/soak.py [--env ID ...] [--episodes N] [--out JSON]

An operator who leaves an evaluation or a training running for hours needs the process to
stay the same size and the same speed: a leak (a cache that only grows, MuJoCo models never
freed, traces kept per episode) shows as resident memory that climbs with the episode count,
and a slowdown as episode times that grow.  Each id runs ``--episodes`` episodes in this one
process, with the default env settings (``estimator="model"``, as a training run sees them)
and random actions from a seeded generator; after every episode the resident set size
(``VmRSS`` of ``/proc/self/status``, or the peak from ``resource.getrusage`` where there is no
``/proc``) and the episode's wall time (reset and step) are recorded.

Reported per id: the median RSS and the median episode time (wall, and the process's CPU
time) over an early window (episodes 10 % to 20 % of the run: past the start, when the scene
caches fill and the allocator warms up) and over the last 10 % (episodes 900-1000 of 1000),
the growth between them in MiB and %, and whether they meet the limits a soak must meet
(growth under ``RSS_LIMIT_MIB``); the windows' CPU times are reported, not limited, since
they hold different scenes.  Single RSS readings vary with the scene (a diced mix's compiled
model is larger than a block's), which is why windows of medians are compared, not ends.

At the end the early window's episodes run again (same seeds and actions): their CPU times
against the first run's, episode by episode, tell a slowdown of the process from the spread
between scenes, and the median of those ratios must stay under ``TIME_LIMIT`` higher (CPU
time, not wall time: on a machine shared with other jobs the wall time follows their load).

The JSON (default ``docs/data/soak.json``) is rewritten atomically every ``--flush`` episodes
and at the end of each id, so a stopped run leaves a valid file with what finished (marked
``"complete": false``); ids already in the file and not run again are kept.
"""

from __future__ import annotations

import argparse
import ctypes
import json
import math
import os
import platform
import resource
import sys
import time
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

import fetch_env

ROOT = Path(__file__).resolve().parents[1]
DEFAULT_OUT = ROOT / "docs" / "data" / "soak.json"
RSS_LIMIT_MIB = 20.0  # most growth of the median RSS, late window against early
TIME_LIMIT = 0.10  # most relative growth of the rerun episodes' CPU time (paired median)
EARLY = (0.10, 0.20)  # share of the run: episodes 100-200 of 1000
LATE = (0.90, 1.00)  # episodes 900-1000 of 1000


def malloc_trim() -> None:
    """Return the C heap's free pages to the system (glibc), so that RSS shows what is in use
    rather than what the allocator keeps; a no-op elsewhere."""
    try:
        ctypes.CDLL("libc.so.6").malloc_trim(0)
    except (OSError, AttributeError):
        pass


def rss_mib() -> float:
    """This process's resident set size now [MiB] (the peak where /proc is missing)."""
    try:
        for line in Path("/proc/self/status").read_text().splitlines():
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024.0  # kB
    except OSError:
        pass
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return peak / (1024.0 * 1024.0 if sys.platform == "darwin" else 1024.0)


def window(n: int, shares: tuple[float, float]) -> slice:
    """Episodes ``shares`` of a run of ``n`` (at least one episode)."""
    lo = min(round(shares[0] * n), n - 1)
    return slice(lo, max(round(shares[1] * n), lo + 1))


def summarize(rss: list[float], wall: list[float], cpu: list[float]) -> dict[str, Any]:
    """Medians over the early and late windows, their growth, and the limits' verdicts (the
    time limit on CPU time, which other jobs on a shared machine do not inflate)."""
    n = len(rss)
    early, late = window(n, EARLY), window(n, LATE)
    r0, r1 = float(np.median(rss[early])), float(np.median(rss[late]))
    t0, t1 = float(np.median(wall[early])), float(np.median(wall[late]))
    c0, c1 = float(np.median(cpu[early])), float(np.median(cpu[late]))
    growth_mib = r1 - r0
    time_change = t1 / t0 - 1.0 if t0 > 0 else math.nan
    cpu_change = c1 / c0 - 1.0 if c0 > 0 else math.nan
    return {
        "episodes": n,
        "early_window": [early.start, early.stop], "late_window": [late.start, late.stop],
        "rss_median_early_mib": round(r0, 2), "rss_median_late_mib": round(r1, 2),
        "rss_growth_mib": round(growth_mib, 2), "rss_growth_pct": round(100 * growth_mib / r0, 2),
        "rss_min_mib": round(min(rss), 2), "rss_max_mib": round(max(rss), 2),
        "episode_s_median_early": round(t0, 4), "episode_s_median_late": round(t1, 4),
        "episode_time_change_pct": round(100 * time_change, 2),
        "episode_cpu_s_median_early": round(c0, 4), "episode_cpu_s_median_late": round(c1, 4),
        "episode_cpu_change_pct": round(100 * cpu_change, 2),
        "rss_ok": bool(growth_mib < RSS_LIMIT_MIB),
    }


def machine() -> dict[str, Any]:
    """Where the soak ran: platform, cores, CPU model, software versions."""
    import mujoco

    cpu = platform.processor() or platform.machine()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    return {"machine": f"{platform.machine()}, {os.cpu_count()} cores ({cpu})",
            "python": platform.python_version(), "mujoco": mujoco.__version__,
            "gymnasium": gym.__version__, "numpy": np.__version__}


def write_atomic(path: Path, data: dict[str, Any]) -> None:
    """Write ``data`` as JSON through a temporary file and ``os.replace``."""
    tmp = path.with_name(path.name + ".part")
    tmp.write_text(json.dumps(data, indent=1) + "\n")
    os.replace(tmp, path)


def load_existing(path: Path) -> dict[str, Any]:
    """The results already in ``path`` (ids run before), or an empty record."""
    try:
        data = json.loads(path.read_text())
    except (OSError, ValueError):
        return {"ids": {}}
    return data if isinstance(data.get("ids"), dict) else {"ids": {}}


def soak(env_id: str, episodes: int, seed: int, record: dict[str, Any], out: Path,
         data: dict[str, Any], flush: int, trim: bool = False) -> dict[str, Any]:
    """Run ``episodes`` episodes of ``env_id`` and fill ``record`` as they finish."""
    env = gym.make(env_id)
    rng = np.random.default_rng(seed)
    rss: list[float] = []
    wall: list[float] = []
    cpu: list[float] = []
    actions: list[np.ndarray] = []
    errors = 0
    load_start = os.getloadavg()[0]
    started = time.perf_counter()
    for ep in range(episodes):
        actions.append(rng.uniform(-1.0, 1.0, 3).astype(np.float32))
        t, c = time.perf_counter(), time.process_time()
        env.reset(seed=seed + ep)
        _, _, _, _, info = env.step(actions[-1])
        wall.append(time.perf_counter() - t)
        cpu.append(time.process_time() - c)
        if trim:
            malloc_trim()
        rss.append(rss_mib())
        errors += "error" in info
        if (ep + 1) % flush == 0 or ep + 1 == episodes:
            record.update(complete=ep + 1 == episodes, seed=seed, episodes_run=ep + 1,
                          diverged=errors, load_average_start=round(load_start, 2),
                          load_average_now=round(os.getloadavg()[0], 2),
                          wall_s=round(time.perf_counter() - started, 1),
                          rss_mib=[round(v, 2) for v in rss],
                          episode_s=[round(v, 4) for v in wall],
                          episode_cpu_s=[round(v, 4) for v in cpu])
            if ep + 1 >= 10:
                record["summary"] = summarize(rss, wall, cpu)
            write_atomic(out, data)
            print(f"{env_id}: {ep + 1}/{episodes} episodes, RSS {rss[-1]:.1f} MiB, "
                  f"{np.median(wall[-flush:]):.3f} s/episode", flush=True)
    record["replay"] = replay(env, seed, actions, cpu)
    write_atomic(out, data)
    env.close()
    return record


def replay(env: Any, seed: int, actions: list[np.ndarray], cpu: list[float]
           ) -> dict[str, Any]:
    """The early window's episodes run again at the end, same seeds and actions: identical
    work, so their CPU times compare the process late in the run with the process early in
    it, free of the scene-to-scene spread that windows of different episodes carry (a diced
    episode's cost varies twofold with its pieces)."""
    early = window(len(actions), EARLY)
    again = []
    for ep in range(early.start, early.stop):
        c = time.process_time()
        env.reset(seed=seed + ep)
        env.step(actions[ep])
        again.append(time.process_time() - c)
    before = np.array(cpu[early])
    ratio = float(np.median(np.array(again) / before))
    return {"episodes": [early.start, early.stop],
            "cpu_s_median_first": round(float(np.median(before)), 4),
            "cpu_s_median_again": round(float(np.median(again)), 4),
            "cpu_s_again": [round(v, 4) for v in again],
            "median_paired_change_pct": round(100 * (ratio - 1.0), 2),
            "time_ok": bool(ratio - 1.0 < TIME_LIMIT)}


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--env", action="append", dest="ids", metavar="ID",
                   help="env id to soak (repeatable; default: every registered id)")
    p.add_argument("--episodes", type=int, default=1000, metavar="N",
                   help="episodes per id (default: 1000; at least 20)")
    p.add_argument("--seed", type=int, default=0, help="first reset seed and action seed")
    p.add_argument("--flush", type=int, default=50, metavar="K",
                   help="rewrite the JSON every K episodes (default: 50)")
    p.add_argument("--malloc-trim", action="store_true",
                   help="call glibc's malloc_trim after every episode (untimed), so that RSS "
                   "counts memory in use, not freed memory the allocator keeps: tells a leak "
                   "from fragmentation")
    p.add_argument("--out", type=Path, default=DEFAULT_OUT, metavar="JSON",
                   help=f"results file (default: {DEFAULT_OUT.relative_to(ROOT)})")
    args = p.parse_args(argv)
    ids = args.ids or list(fetch_env.ENV_IDS)
    unknown = [i for i in ids if i not in fetch_env.ENV_IDS]
    if unknown or args.episodes < 20 or args.flush < 1:
        p.error(f"unknown id(s) {unknown}" if unknown else "--episodes >= 20, --flush >= 1")
    data = load_existing(args.out)
    here = machine()
    command = "python " + " ".join(["benchmarks/soak.py",
                                    *(sys.argv[1:] if argv is None else argv)])
    # ids kept from an earlier run keep the machine and command that measured them
    for run in data["ids"].values():
        run.setdefault("machine", data.get("machine", {}).get("machine", "unknown"))
        run.setdefault("command", data.get("command", "unknown"))
    data.update(machine=here, limits={"rss_growth_mib": RSS_LIMIT_MIB,
                                      "episode_time_change": TIME_LIMIT},
                windows={"early": list(EARLY), "late": list(LATE)}, command=command)
    for env_id in ids:
        record = data["ids"][env_id] = {"malloc_trim": args.malloc_trim,
                                        "machine": here["machine"], "command": command}
        soak(env_id, args.episodes, args.seed, record, args.out, data, args.flush,
             args.malloc_trim)
        s = record["summary"]
        print(f"{env_id}: RSS median {s['rss_median_early_mib']:.1f} -> "
              f"{s['rss_median_late_mib']:.1f} MiB ({s['rss_growth_mib']:+.1f} MiB, "
              f"{s['rss_growth_pct']:+.1f} %), episode {s['episode_s_median_early']:.3f} -> "
              f"{s['episode_s_median_late']:.3f} s ({s['episode_time_change_pct']:+.1f} %), CPU "
              f"{s['episode_cpu_s_median_early']:.3f} -> {s['episode_cpu_s_median_late']:.3f} s "
              f"({s['episode_cpu_change_pct']:+.1f} %); the early window run again at the "
              f"end: CPU {record['replay']['median_paired_change_pct']:+.1f} % (paired median)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
