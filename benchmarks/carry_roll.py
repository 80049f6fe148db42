"""Does a roll toward the mouth make the squeeze matter?  The light touch rolled to pi/2.

Run: python benchmarks/carry_roll.py [--env ID ...] [--seeds 100:140] [--workers 2] [--out JSON]
     python benchmarks/carry_roll.py --seeds 80000:80040 --out docs/data/carry_roll_heldout.json
     python benchmarks/carry_roll.py --table   (docs/agents.md's table from both JSON files)

A bite carried to a mouth is tipped: rolling the closed pair about the clamp direction puts
the piece's weight along the hinge axis, where the half-spoons' V does not wedge it and only
the faces' friction holds it (:mod:`fetch_env.carry`).  If that load decided whether a light
touch holds, the squeeze would have to follow the food's friction and stiffness, and a
benchmark with such a carry would reward reading them.  This script fetches each tuning scene
(default seeds 100-139 of Block-v1, Row-v1 and TwoRows-v2) at the id's best constant action
(``benchmarks/theta_sweep.py``: the lightest touch, fastest clamp and lift) with a 1 s air
hold, once as it is and once rolled to pi/2 (the whole weight along the hinge axis, ramped
over 0.4 s), and records which pieces each holds, and for single pieces the grip's margin
``2 mu N / (m g)`` at the end of the unrolled air hold (N from the blades' normal force).
Where the roll drops a piece the unrolled fetch held, the scene's twin (every piece moved
1 nm) is fetched both ways too: a drop the twin does not repeat is the chaos of a
multi-piece fetch, not the carry.

The JSON (default ``docs/data/carry_roll.json``) is rewritten atomically after every scene,
with ``"complete": false`` until the end: Ctrl-C, SIGTERM or a lost worker ends the run in
one line with every finished scene in the file.
"""

from __future__ import annotations

import argparse
import concurrent.futures as cf
import json
import math
import sys
import time
from collections.abc import Callable
from concurrent.futures.process import BrokenProcessPool
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

import fetch_env  # noqa: F401  (registers the ids)
from fetch_env.controller import PHASE_CODE, FetchAction, FetchSimulator

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from agents.evaluate import _close_pool  # noqa: E402
from benchmarks.bench_quasi_static import seeded_twin  # noqa: E402
from benchmarks.readme_meta import meta, rewrite_block, write_json  # noqa: E402
from benchmarks.theta_sweep import LIFT_SPEED, OMEGA, seed_range  # noqa: E402
from fetch_env.parallel import stop_exit_code, stop_on_signals, worker_signals  # noqa: E402

# The best constant clamp angle of each id on these tuning scenes (docs/data/theta_sweep/).
BEST_THETA = {"FoodFetch-Block-v1": 0.05, "FoodFetch-Row-v1": 0.03,
              "FoodFetch-TwoRows-v2": 0.05}
AIR_HOLD = 1.0  # [s] the roll's 0.4 s ramp, then 0.6 s held
ROLL = 0.5 * math.pi  # [rad]
DATA = ROOT / "docs" / "data" / "carry_roll.json"  # the tuning scenes (seeds 100-139)
HELD_OUT = ROOT / "docs" / "data" / "carry_roll_heldout.json"  # seeds never tuned on
DOC = ROOT / "docs" / "agents.md"
MARK = ("<!-- carry-roll-table -->", "<!-- /carry-roll-table -->")


def roll_scene(env_id: str, seed: int) -> dict[str, Any]:
    """One scene fetched at the id's best constant action, unrolled and rolled."""
    env = gym.make(env_id, estimator="oracle")  # the observation is not used here
    env.reset(seed=seed)
    u = env.unwrapped
    sim = FetchSimulator(u.pieces, u.geometry, timestep=u.fetch_timestep,
                         impratio=u.fetch_impratio)
    base = dict(theta_d=BEST_THETA[env_id], omega=OMEGA, lift_speed=LIFT_SPEED,
                hold=u._episode_hold, lift_height=u.lift_height, air_hold=AIR_HOLD,
                settle=u.settle)
    flat = sim.run("fetch", FetchAction(**base))
    rolled = sim.run("fetch", FetchAction(**base, tilt=ROLL))
    record: dict[str, Any] = {
        "seed": seed, "pieces": len(u.pieces),
        "young": u.pieces[0].material.young, "mu": u.pieces[0].material.mu,
        "size": u.pieces[0].size,
        "held": [p["fetched"] for p in flat.pieces],
        "held_rolled": [p["fetched"] for p in rolled.pieces],
        "slid_mm": [round(1e3 * (b["final_centre"][0] - a["final_centre"][0]), 3)
                    for a, b in zip(flat.pieces, rolled.pieces, strict=True)]}
    if _dropped(record["held"], record["held_rolled"]):
        # the carry, or the chaos of a multi-piece fetch?  The same scene, moved 1 nm.
        twin = FetchSimulator(seeded_twin(u.pieces, seed), u.geometry, timestep=u.fetch_timestep,
                              impratio=u.fetch_impratio)
        record["twin_held"] = [p["fetched"] for p in twin.run("fetch", FetchAction(**base)).pieces]
        record["twin_held_rolled"] = [
            p["fetched"] for p in twin.run("fetch", FetchAction(**base, tilt=ROLL)).pieces]
    if len(u.pieces) == 1 and flat.fetch_rate == 1.0:
        tr = flat.traces
        last = np.flatnonzero(tr["phase"] == PHASE_CODE["air"])[-1]
        normal = 0.5 * (abs(tr["normal_left"][last]) + abs(tr["normal_right"][last]))
        weight = u.pieces[0].mass * 9.81
        record["margin"] = round(float(2 * u.pieces[0].material.mu * normal / weight), 3)
    env.close()
    return record


def _dropped(held: list[bool], held_rolled: list[bool]) -> int:
    """Pieces held unrolled and dropped rolled."""
    return sum(a and not b for a, b in zip(held, held_rolled, strict=True))


def summarize(records: list[dict[str, Any]]) -> dict[str, Any]:
    held = sum(sum(r["held"]) for r in records)
    kept = sum(sum(a and b for a, b in zip(r["held"], r["held_rolled"], strict=True))
               for r in records)
    margins = [r["margin"] for r in records if "margin" in r]
    out: dict[str, Any] = {
        "scenes": len(records), "pieces": sum(r["pieces"] for r in records),
        "held": held, "held_rolled": sum(sum(r["held_rolled"]) for r in records),
        "held_then_dropped_rolled": held - kept,
        # of those scenes, the same drop on the 1 nm twin (the carry, not the chaos)
        "dropped_rolled_on_twin": sum(_dropped(r["twin_held"], r["twin_held_rolled"])
                                      for r in records if "twin_held" in r),
        "scenes_changed": sum(r["held"] != r["held_rolled"] for r in records),
        # how far a piece held both ways moved along the hinge axis under the roll
        "largest_slide_mm": max((abs(s) for r in records for s, a, b in zip(
            r["slid_mm"], r["held"], r["held_rolled"], strict=True) if a and b), default=0.0)}
    if margins:
        out["margin_min"], out["margin_median"] = min(margins), float(np.median(margins))
    return out


def table_markdown(paths: tuple[Path, ...] = (DATA, HELD_OUT)) -> str:
    """The docs table: per id and set of scenes (the tuning scenes the best constant action
    was chosen on, then scenes never tuned on), pieces held at that action, unrolled and
    rolled; a set not yet run is left out."""
    lines = ["| id | theta_d | scenes | pieces held | held rolled to pi/2 | held, then dropped "
             "rolled (on the scene's 1 nm twin) | largest slide along the hinge axis | grip "
             "margin 2 mu N / (m g), least / median |", "|---|---|---|---|---|---|---|---|"]
    footers = []
    for path in paths:
        if not path.exists():
            continue
        data = json.loads(path.read_text())
        for env_id, block in data["ids"].items():
            s = block["summary"]
            seeds = [r["seed"] for r in block["scenes"]]
            margin = (f"{s['margin_min']:.1f} / {s['margin_median']:.0f}" if "margin_min" in s
                      else "-")
            lines.append(f"| {env_id} | {data['best_theta'][env_id]:g} rad | {s['scenes']} "
                         f"(seeds {min(seeds)}-{max(seeds)}) | {s['held']} of {s['pieces']} | "
                         f"{s['held_rolled']} | {s['held_then_dropped_rolled']} "
                         f"({s['dropped_rolled_on_twin']}) | "
                         f"{s['largest_slide_mm']:.1f} mm | {margin} |")
        m = data["meta"]
        where = f"{m['machine']}, at {m.get('code', m['commit'])}"
        footers.append((where, f"{m['wall_s'] / 60:.0f} min: `{m['command']}`"))
    places = list(dict.fromkeys(where for where, _ in footers))
    text = "; ".join(f"{where}: " + "; ".join(run for w, run in footers if w == where)
                     for where in places)
    return "\n".join([*lines, "", text])


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--env", action="append", choices=sorted(BEST_THETA),
                    help="id (repeatable; default: all three)")
    ap.add_argument("--seeds", type=seed_range, default=range(100, 140))
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--out", type=Path, default=DATA)
    ap.add_argument("--table", action="store_true",
                    help="rewrite docs/agents.md's table from the committed JSON files and stop")
    args = ap.parse_args(argv)
    if args.table:
        rewrite_block(DOC, MARK[0], MARK[1], table_markdown())
        return 0
    if args.workers < 1:
        ap.error(f"--workers must be >= 1, got {args.workers}")
    ids = args.env or sorted(BEST_THETA)
    records: dict[str, list[dict[str, Any]]] = {i: [] for i in ids}
    start = time.time()

    saved = []  # whether --out was written

    def save(complete: bool = False) -> None:
        out = {"meta": meta(time.time() - start), "roll": ROLL, "air_hold": AIR_HOLD,
               "best_theta": {i: BEST_THETA[i] for i in ids},
               "ids": {i: {"summary": summarize(sorted(r, key=lambda x: x["seed"])),
                           "scenes": sorted(r, key=lambda x: x["seed"])}
                       for i, r in records.items() if r}, "complete": complete}
        write_json(args.out, out)
        saved.append(True)

    stop_on_signals()
    try:
        _roll_all(ids, args.seeds, args.workers, records, save)
    except (KeyboardInterrupt, BrokenProcessPool) as exc:
        why = "stopped" if isinstance(exc, KeyboardInterrupt) else "a worker died"
        kept = (f"what finished is in {args.out} (\"complete\": false)" if saved
                else f"no scene finished; {args.out} is as it was")
        print(f"carry_roll: {why}; {kept}", file=sys.stderr)
        return stop_exit_code(exc) if isinstance(exc, KeyboardInterrupt) else 1
    save(complete=True)
    for i in ids:
        print(i, summarize(records[i]))
    return 0


def _roll_all(ids: list[str], seeds: range, workers: int,
              records: dict[str, list[dict[str, Any]]], save: Callable[[], None]) -> None:
    """Every id's scenes on a process pool, each kept (``save``) as it finishes."""
    pool = cf.ProcessPoolExecutor(workers, initializer=worker_signals)
    clean = False
    try:
        jobs = {pool.submit(roll_scene, i, s): i for i in ids for s in seeds}
        for job in cf.as_completed(jobs):
            records[jobs[job]].append(job.result())
            save()
        clean = True
    finally:
        _close_pool(pool, clean)  # after a stop or a lost worker, the workers end too




if __name__ == "__main__":
    raise SystemExit(main())
