"""Quasi-static fetch holds: how far they move each id's outcomes, against the chaos floor,
and what they save.

For each id and seeded scene (``reset(seed=S)``, one action drawn uniformly from the action
box with a generator seeded by S), the same fetch is simulated by ``simulate_action``:

* in real time (``fetch_hold_scale=1``, every id's default): the reference;
* on its **twin**, the scene with every piece moved 1 nm along x (a seeded sign per piece),
  in real time: how much a change of nothing physical moves the outcome, the chaos floor;
* with each ``fetch_hold_scale`` asked for (the holds on the plate and in the air past their
  first 0.1 s stepped quasi-statically), and each ``--runs`` pair of a hold scale and a
  ``fetch_clamp_speed`` (a clamp slower than that simulated at it, quasi-statically).

Per run: each piece fetched or not, the reward and the step's CPU time (the fetch; the
reset's CPU time is taken once per scene, from the reference env, to turn fetch savings into
episodes per core).  A scale is as good as the physics allows where its pieces agree with the
reference as often as the twin's do and its paired reward difference is as small.

Each scene is kept as it finishes (``--json`` rewritten atomically, ``"complete": false``
until the end): Ctrl-C, SIGTERM or a lost worker ends the run in one line with every
finished scene and its id's summary in the file.

Run: python benchmarks/bench_quasi_static.py --seeds 60000:60040 --runs 5,1:0.1,5:0.1 \\
       --workers 2 --json docs/data/quasi_static.json
     python benchmarks/bench_quasi_static.py --page docs/data/quasi_static.json
"""

from __future__ import annotations

import argparse
import json
import math
import statistics
import sys
import time
import warnings
from collections.abc import Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from concurrent.futures.process import BrokenProcessPool
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import fetch_env  # noqa: F401  (registers the ids)
from agents.evaluate import _close_pool
from benchmarks.bench_step_size import twin_of
from benchmarks.readme_meta import meta, rewrite_block, write_json
from fetch_env.layouts import Piece
from fetch_env.parallel import stop_exit_code, stop_on_signals, worker_signals

ROOT = Path(__file__).resolve().parents[1]
PAGE = ROOT / "docs" / "validation" / "quasi-static-holds.md"
DEFAULT_IDS = ("FoodFetch-Block-v1", "FoodFetch-Row-v1", "FoodFetch-TwoRows-v1",
               "FoodFetch-Diced-v1")


def seeded_twin(pieces: Sequence[Piece], seed: int) -> tuple[Piece, ...]:
    """Scene ``seed``'s twin (:func:`benchmarks.bench_step_size.twin_of`), a sign a piece
    drawn from ``seed``."""
    return twin_of(pieces, np.random.default_rng(seed).choice([-1.0, 1.0], size=len(pieces)))


def _fetch(env: gym.Env, action: np.ndarray) -> dict[str, Any]:
    t = time.thread_time()
    reward, info = env.unwrapped.simulate_action(action)
    cpu = time.thread_time() - t
    return {"reward": float(reward), "cpu": cpu,
            "fetched": [bool(p["fetched"]) for p in info.get("pieces", [])],
            "error": info.get("error")}


Run = tuple[float, float]  # (fetch_hold_scale, fetch_clamp_speed)
# A scene's reward "falls" where a run's is this much below the real-time fetch's: a tenth
# of a single piece's worth, far past the time cost's share of a changed clamp.
REWARD_FALL = 0.1


def run_name(run: Run) -> str:
    """A run's key in the JSON: ``x5`` (holds scaled by 5), ``x5c0.2`` (and the clamp
    simulated at 0.2 rad/s where slower), ``x1c0.2`` (the clamp alone)."""
    scale, clamp = run
    return f"x{scale:g}" + (f"c{clamp:g}" if clamp else "")


def run_kwargs(name: str) -> dict[str, float]:
    """A run's key (:func:`run_name`) as env kwargs."""
    scale, _, clamp = name[1:].partition("c")
    return {"fetch_hold_scale": float(scale), "fetch_clamp_speed": float(clamp or 0.0)}


def run_label(name: str) -> str:
    """The page's words for a run's key."""
    run = run_kwargs(name)
    scale, clamp = run["fetch_hold_scale"], run["fetch_clamp_speed"]
    parts = [f"hold scale {scale:g}"] if scale != 1 else []
    parts += [f"slow clamps run at {clamp:g} rad/s"] if clamp else []
    return ", ".join(parts)


def run_scene(env_id: str, seed: int, runs: tuple[Run, ...]) -> dict[str, Any]:
    """The reference, its twin and each run on one seeded scene and action."""
    warnings.simplefilter("ignore")  # clipped moduli: said once per env elsewhere
    action = np.random.default_rng(seed).uniform(-1.0, 1.0, 3).astype(np.float32)
    ref = gym.make(env_id)
    t = time.thread_time()
    ref.reset(seed=seed)
    out: dict[str, Any] = {"seed": seed, "reset_cpu": time.thread_time() - t,
                           "n_pieces": len(ref.unwrapped.pieces), "ref": _fetch(ref, action)}
    pieces = ref.unwrapped.pieces
    ref.reset(seed=seed, options={"pieces": seeded_twin(pieces, seed)})
    out["twin"] = _fetch(ref, action)
    ref.close()
    for scale, clamp in runs:
        env = gym.make(env_id, fetch_hold_scale=scale, fetch_clamp_speed=clamp)
        env.reset(seed=seed)
        out[run_name((scale, clamp))] = _fetch(env, action)
        env.close()
    return out


def summarize(records: list[dict[str, Any]], runs: list[str]) -> dict[str, Any]:
    """Per run: pieces and scenes as the reference, the paired reward difference (mean, its
    standard error, median of its size), and the fetch's and the episode's CPU against the
    reference's."""
    n_pieces = sum(len(r["ref"]["fetched"]) for r in records)
    ref_cpu = sum(r["ref"]["cpu"] for r in records)
    reset_cpu = sum(r["reset_cpu"] for r in records)
    out: dict[str, Any] = {"scenes": len(records), "pieces": n_pieces}
    for run in runs:
        same = sum(a == b for r in records
                   for a, b in zip(r["ref"]["fetched"], r[run]["fetched"], strict=False))
        whole = sum(r["ref"]["fetched"] == r[run]["fetched"] for r in records)
        diff = [r[run]["reward"] - r["ref"]["reward"] for r in records]
        cpu = sum(r[run]["cpu"] for r in records)
        out[run] = {
            "pieces_as_reference": same, "scenes_as_reference": whole,
            "reward_falls": sum(d < -REWARD_FALL for d in diff),
            "reward_diff_mean": statistics.fmean(diff),
            "reward_diff_se": (statistics.stdev(diff) / math.sqrt(len(diff)) if len(diff) > 1
                               else math.nan),
            "reward_diff_abs_median": statistics.median(abs(d) for d in diff),
            "fetch_cpu_ratio": cpu / ref_cpu,
            "episode_speedup": (reset_cpu + ref_cpu) / (reset_cpu + cpu),
            "errors": sum(r[run]["error"] is not None for r in records)}
    return out


def at_chaos_floor(summary: dict[str, Any], run: str) -> bool:
    """Whether ``run`` is at the chaos floor (the rule each id's quasi-static setting is
    chosen by): its pieces ended fetched or not as in the real-time fetch at least as often
    as the 1 nm twin's, less one piece, and its reward fell by more than ``REWARD_FALL``
    below the real-time fetch's on at most one scene more than the twin's did (a fetch
    clamped faster than it was asked overshoots its squeeze and crushes more; chance moves
    a reward either way), with no more failed fetches than the twin's."""
    run_s, twin = summary[run], summary["twin"]
    return (run_s["pieces_as_reference"] >= twin["pieces_as_reference"] - 1
            and run_s["reward_falls"] <= twin["reward_falls"] + 1
            and run_s["errors"] <= twin["errors"])


def fastest_at_floor(summary: dict[str, Any], runs: Sequence[str]) -> str | None:
    """Of ``runs``, the one with the most episodes per core that is :func:`at_chaos_floor`
    on ``summary`` (one id's), or None."""
    passing = [r for r in runs if r in summary and at_chaos_floor(summary, r)]
    return max(passing, key=lambda r: summary[r]["episode_speedup"], default=None)


def validated_setting(tuning: dict[str, Any], reporting: dict[str, Any], runs: Sequence[str],
                      fallback: str) -> str:
    """One id's setting: the fastest of ``runs`` at the chaos floor on its ``tuning``
    summary, kept where it is at the floor on ``reporting`` too (other scenes), else
    ``fallback`` (which must be at the floor on both; the next-fastest candidate is not
    tried, as that would choose on the other scenes)."""
    for which, s in (("tuning", tuning), ("reporting", reporting)):
        missing = [r for r in ("twin", fallback) if r not in s]
        if missing:
            raise ValueError(f"the {which} runs have no {missing[0]!r}")
    chosen = fastest_at_floor(tuning, runs)
    if chosen is not None and at_chaos_floor(reporting, chosen):
        return chosen
    if not (at_chaos_floor(tuning, fallback) and at_chaos_floor(reporting, fallback)):
        raise ValueError(f"the fallback {fallback} is not at the chaos floor")
    return fallback


def page(data: dict[str, Any]) -> str:
    """The validation page's results table and footer, from the JSON."""
    lines = ["| id | run | pieces as real time | scenes as real time | reward - real time "
             "(paired mean ± s.e.) | median abs reward change | fetch CPU | episodes per "
             "core |", "|---|---|---|---|---|---|---|---|"]
    for env_id, s in data["summary"].items():
        for run in ("twin", *data["runs"]):
            r = s[run]
            name = "1 nm twin (chaos floor)" if run == "twin" else run_label(run)
            lines.append(
                f"| {env_id.removeprefix('FoodFetch-')} | {name} | {r['pieces_as_reference']} "
                f"/ {s['pieces']} ({r['pieces_as_reference'] / s['pieces']:.1%}) | "
                f"{r['scenes_as_reference']} / {s['scenes']} | {r['reward_diff_mean']:+.3f} ± "
                f"{r['reward_diff_se']:.3f} | {r['reward_diff_abs_median']:.3f} | "
                f"{r['fetch_cpu_ratio']:.2f}x | {r['episode_speedup']:.2f}x |")
    m = data["meta"]
    lines += ["", f"{m['machine']}, at {m.get('code', m['commit'])}; scenes from seed "
              f"{data['seeds'][0]} to "
              f"{data['seeds'][1] - 1} per id: `{m['command']}`"]
    return "\n".join(lines)


# Each id's own setting (fetch_env.quasi_static.QUASI_STATIC): the candidates, chosen on the
# tuning scenes' files and held to the reporting scenes' (seeds 60000-60039).
CANDIDATES: tuple[str, ...] = ("x5c0.1", "x5c0.2", "x5c0.4")
FALLBACK = "x5c0.1"
ID_TUNING: tuple[Path, ...] = (ROOT / "docs/data/tuning/quasi_static_clamp_speeds.json",
                               ROOT / "docs/data/tuning/quasi_static_clamp_speeds_v2v3.json")
ID_REPORTING: tuple[Path, ...] = (ROOT / "docs/data/quasi_static_clamp_speeds.json",
                                  ROOT / "docs/data/quasi_static_clamp_speeds_v2v3.json")


def _summaries(paths: Sequence[Path]) -> dict[str, dict[str, Any]]:
    """Each id's summary, recomputed from the files' records (:func:`summarize`)."""
    out: dict[str, dict[str, Any]] = {}
    for path in paths:
        data = json.loads(path.read_text())
        for env_id, records in data["records"].items():
            if env_id in out:
                raise ValueError(f"{env_id} is in more than one of {[str(p) for p in paths]}")
            out[env_id] = summarize(records, ["twin", *data["runs"]])
    return out


def id_settings(tuning: Sequence[Path] = ID_TUNING, reporting: Sequence[Path] = ID_REPORTING
                ) -> dict[str, dict[str, Any]]:
    """Per id measured in both: the candidate chosen on ``tuning``, the setting kept
    (:func:`validated_setting`) and its summaries on both sets."""
    tun, rep = _summaries(tuning), _summaries(reporting)
    out = {}
    for env_id in (i for i in tun if i in rep):
        kept = validated_setting(tun[env_id], rep[env_id], CANDIDATES, FALLBACK)
        out[env_id] = {"chosen": fastest_at_floor(tun[env_id], CANDIDATES), "kept": kept,
                       "tuning": tun[env_id], "reporting": rep[env_id]}
    return out


def settings_page(settings: dict[str, dict[str, Any]]) -> str:
    """The page's table of each id's setting: pieces as real time on both sets (hold scale
    5 and each candidate clamp speed), the one chosen on the tuning scenes and the one
    kept."""
    def speed(run: str | None) -> str:
        return "-" if run is None else f"{run_kwargs(run)['fetch_clamp_speed']:g} rad/s"

    def pieces(s: dict[str, Any]) -> str:
        each = (f"{s[x]['pieces_as_reference']} ({s[x]['reward_falls']})" if x in s else "-"
                for x in ("twin", *CANDIDATES))
        return f"{' / '.join(each)} of {s['pieces']}"

    lines = ["| id | tuning scenes, pieces as real time (scenes whose reward fell): twin / "
             + " / ".join(speed(c) for c in CANDIDATES)
             + " | chosen | other scenes, the same | kept | its episodes per core |",
             "|---|---|---|---|---|---|"]
    for env_id, r in settings.items():
        lines.append(f"| {env_id.removeprefix('FoodFetch-')} | {pieces(r['tuning'])} | "
                     f"{speed(r['chosen'])} | {pieces(r['reporting'])} | {speed(r['kept'])} | "
                     f"{r['reporting'][r['kept']]['episode_speedup']:.2f}x |")
    return "\n".join(lines)


BEGIN = "<!-- quasi-static-table: generated by benchmarks/bench_quasi_static.py --page -->"
END = "<!-- /quasi-static-table -->"
TUNING_BEGIN = ("<!-- quasi-static-tuning-table: generated by benchmarks/bench_quasi_static.py "
                "--tuning-page -->")
TUNING_END = "<!-- /quasi-static-tuning-table -->"


IDS_BEGIN = ("<!-- quasi-static-ids-table: generated by benchmarks/bench_quasi_static.py "
             "--ids-page -->")
IDS_END = "<!-- /quasi-static-ids-table -->"
IDS_RUNS_BEGIN = ("<!-- quasi-static-ids-runs-table: generated by "
                  "benchmarks/bench_quasi_static.py --ids-page -->")
IDS_RUNS_END = "<!-- /quasi-static-ids-runs-table -->"


def write_ids_page(path: Path = PAGE) -> None:
    """Rewrite the page's tables of each id's setting and of the runs they rest on (every
    file of ``ID_TUNING`` after the first, which the tuning table shows, and of
    ``ID_REPORTING``)."""
    rewrite_block(path, IDS_BEGIN, IDS_END, settings_page(id_settings()))
    runs = [page(json.loads(p.read_text())) for p in (*ID_TUNING[1:], *ID_REPORTING)]
    rewrite_block(path, IDS_RUNS_BEGIN, IDS_RUNS_END, "\n\n".join(runs))


def write_page(data: dict[str, Any], path: Path = PAGE, tuning: bool = False) -> None:
    """Rewrite the page's results table (``tuning``: the tuning scenes' table) from ``data``."""
    begin, end = (TUNING_BEGIN, TUNING_END) if tuning else (BEGIN, END)
    rewrite_block(path, begin, end, page(data))


def _seed_range(text: str) -> tuple[int, int]:
    a, _, b = text.partition(":")
    try:
        lo, hi = int(a), int(b)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not START:STOP") from None
    if not 0 <= lo < hi:
        raise argparse.ArgumentTypeError(f"{text!r}: need 0 <= START < STOP")
    return lo, hi


def _scales(text: str) -> tuple[float, ...]:
    try:
        out = tuple(float(x) for x in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a list of numbers") from None
    bad = [k for k in out if not 1 < k <= 20]
    if bad:
        raise argparse.ArgumentTypeError(f"scale {bad[0]:g} is not in (1, 20]")
    return out


def _runs(text: str) -> tuple[Run, ...]:
    """``K`` or ``K:S`` items: a hold scale in [1, 20] and a clamp speed, 0 or 0.05-0.4."""
    out = []
    for item in text.split(","):
        a, _, b = item.partition(":")
        try:
            run = (float(a), float(b) if b else 0.0)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{item!r} is not K or K:S") from None
        if not 1 <= run[0] <= 20:
            raise argparse.ArgumentTypeError(f"{item!r}: scale {run[0]:g} is not in [1, 20]")
        if not (run[1] == 0 or 0.05 <= run[1] <= 0.4):
            raise argparse.ArgumentTypeError(
                f"{item!r}: clamp speed {run[1]:g} is not 0 or in [0.05, 0.4] rad/s")
        if run == (1.0, 0.0):
            raise argparse.ArgumentTypeError(f"{item!r} is the reference itself")
        out.append(run)
    return tuple(out)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--ids", nargs="+", default=list(DEFAULT_IDS))
    p.add_argument("--seeds", type=_seed_range, default=(60000, 60040), metavar="START:STOP")
    p.add_argument("--scales", type=_scales, default=(), metavar="K[,K...]",
                   help="hold scales alone (as --runs K,...)")
    p.add_argument("--runs", type=_runs, default=(), metavar="K[:S][,...]",
                   help="hold scale K with clamps slower than S rad/s run at S")
    p.add_argument("--workers", type=int, default=1)
    p.add_argument("--json", type=Path, default=None, metavar="FILE")
    p.add_argument("--page", type=Path, default=None, metavar="FILE",
                   help="only rewrite docs/validation/quasi-static-holds.md's table from FILE")
    p.add_argument("--tuning-page", type=Path, default=None, metavar="FILE",
                   help="only rewrite that page's tuning-scene table from FILE")
    p.add_argument("--ids-page", action="store_true",
                   help="only rewrite that page's tables of each id's own setting "
                   "(fetch_env.quasi_static) from the committed runs")
    args = p.parse_args(argv)
    if args.ids_page:
        write_ids_page()
        return 0
    if args.page is not None or args.tuning_page is not None:
        for path, tuning in ((args.page, False), (args.tuning_page, True)):
            if path is not None:
                try:
                    data = json.loads(path.read_text())
                except (OSError, ValueError) as exc:
                    p.error(f"{path}: {exc}")
                write_page(data, tuning=tuning)
        return 0
    unknown = [i for i in args.ids if i not in gym.registry]
    if unknown:
        p.error(f"--ids: {unknown[0]!r} is not a registered id")
    if args.workers < 1:
        p.error(f"--workers must be >= 1, got {args.workers}")
    args.runs = tuple(dict.fromkeys([*((k, 0.0) for k in args.scales), *args.runs]))
    if not args.runs:
        args.runs = ((5.0, 0.0),)
    runs = ["twin", *map(run_name, args.runs)]
    data: dict[str, Any] = {"meta": meta(), "seeds": list(args.seeds), "runs": runs[1:],
                            "summary": {}, "records": {}, "complete": False}
    stop_on_signals()
    try:
        _measure(args, runs, data)
    except (KeyboardInterrupt, BrokenProcessPool) as exc:
        why = "stopped" if isinstance(exc, KeyboardInterrupt) else "a worker died"
        kept = f"what finished is in {args.json}" if args.json else "--json FILE keeps it"
        print(f"bench_quasi_static: {why}; {kept} (\"complete\": false)", file=sys.stderr)
        return stop_exit_code(exc) if isinstance(exc, KeyboardInterrupt) else 1
    print(page(data))
    return 0


def _measure(args: argparse.Namespace, runs: list[str], data: dict[str, Any]) -> None:
    """Run every id's scenes, keeping each scene as it finishes: ``data`` (and ``--json``,
    rewritten atomically) holds every finished scene, in seed order, and each id's summary
    of them, whenever the run stops."""
    seeds = list(range(*args.seeds))
    pool = ProcessPoolExecutor(args.workers, initializer=worker_signals)
    clean = False
    try:
        for env_id in args.ids:
            done: dict[int, dict[str, Any]] = {}
            futures = [pool.submit(run_scene, env_id, seed, args.runs) for seed in seeds]
            for future in as_completed(futures):
                record = future.result()
                done[record["seed"]] = record
                data["records"][env_id] = [done[k] for k in sorted(done)]
                data["summary"][env_id] = summarize(data["records"][env_id], runs)
                if args.json is not None:
                    write_json(args.json, data)
        clean = True
    finally:
        _close_pool(pool, clean)  # after a stop or a lost worker, the workers end too
    data["complete"] = True
    if args.json is not None:
        write_json(args.json, data)


if __name__ == "__main__":
    raise SystemExit(main())
