"""Very soft packed plates: where the simulator stops resolving a two-row plate.

Run: python benchmarks/very_soft_plates.py [--out docs/data/very_soft_plates.json]
     python benchmarks/very_soft_plates.py --spaced [--out docs/data/very_soft_plates_spaced.json]
     python benchmarks/very_soft_plates.py --levels FoodFetch-TwoRows-v2 [--out JSON]

Two checks, at the fastest clamp and lift (0.4 rad/s, 40 mm/s), on FoodFetch-TwoRows-v1:

1. 0.0123 MPa 10 mm cubes in four arrangements at five clamp angles: one cube, a pair along
   the clamp, a row of two across it (0.01 mm apart) and a 2 x 2 plate; then the 2 x 2 plate
   with its cubes 1, 0.3 and 0.01 mm apart across the clamp (1 mm along).  A plate the
   simulator resolves deforms smoothly as the squeeze grows (its largest logarithmic strain
   LE rises); one it does not is flung apart (LE of several, pieces moved tens of mm).
2. Three very soft tuning plates (``reset(seed=s)``, seeds of the tuning set 100-139) at the
   default settings, at a 2.5 ms fetch step, and at friction impratio 1000: whether the
   outcome is the physics' or the numerics'.

With ``--spaced``, a third check alone: 3. every 0.0123 MPa plate of the tuning seeds 100-139
rebuilt with its rows 1 mm apart across the clamp (0.01 mm in the id; the same cubes, sizes
and material, 1 mm along) and fetched at clamp angles from 0.03 to 0.10 rad: whether the
spacing that resolves the 2 x 2 plate of check 1 makes the id's very soft plates a choice of
angle rather than a lottery.

With ``--levels ID``, a fourth check alone: 4. every plate of the id's softest level among
the tuning seeds 100-139 (FoodFetch-TwoRows-v1: 0.0123 MPa; -v2 and -v3: 0.06 MPa) fetched at
three clamp angles (-v3: deeper, where its round pieces are held) under the three settings of
check 2: how often the settings disagree on the
outcome (rewards more than 0.5 apart), i.e. how often the plate's outcome is the numerics'
rather than the action's.  This is how the -v2 id's softest level was checked.

Each fetch's reward, fetch rate, largest LE in the clamp and hold, and the farthest piece's
final distance across the clamp are written to the JSON, rewritten atomically after each
check so that a stopped run keeps what finished.
"""

from __future__ import annotations

import argparse
import math
import sys
import warnings
from pathlib import Path
from typing import Any

import gymnasium as gym

import fetch_env  # noqa: F401  (registers the ids)
from fetch_env.env import physical_to_action
from fetch_env.env_scenes import TWO_ROWS_SPACING_ALONG
from fetch_env.layouts import Piece, grid, single_block, two_rows
from fetch_env.materials import PRESETS

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from benchmarks.readme_meta import meta, write_json  # noqa: E402

ENV_ID = "FoodFetch-TwoRows-v1"
SOFT = PRESETS["very-soft-0.0123MPa"]
THETAS = (0.04, 0.05, 0.06, 0.07, 0.09)  # [rad]
SEEDS_AND_ANGLES = ((100, 0.03), (104, 0.06), (117, 0.055))  # tuning plates
SETTINGS: dict[str, dict[str, float]] = {
    "default": {}, "step 2.5 ms": {"fetch_timestep": 0.0025},
    "impratio 1000": {"fetch_impratio": 1000.0}}


def fetch(env: gym.Env, theta: float, pieces: tuple[Piece, ...] | None = None,
          seed: int | None = None) -> dict[str, Any]:
    """One fetch of ``pieces`` (or of the scene of ``seed``) at ``theta`` [rad]."""
    if pieces is not None:
        env.reset(options={"pieces": list(pieces)})
    else:
        env.reset(seed=seed)
    _, reward, _, _, info = env.step(physical_to_action(theta, 0.4, 0.04))
    return {"theta": theta, "reward": round(float(reward), 4),
            "fetch_rate": info["fetch_rate"],
            "le_max": round(max(p["max_log_strain_clamp"] for p in info["pieces"]), 3),
            "farthest_x_mm": round(1e3 * max(abs(p["final_centre"][0])
                                             for p in info["pieces"]), 1)}


def arrangements() -> list[dict[str, Any]]:
    """Check 1: the arrangements at every angle, then the 2 x 2 plate's spacing across."""
    env = gym.make(ENV_ID, estimator="none")
    plates = {"one cube": single_block("cube", 0.010, SOFT),
              "pair along the clamp": grid(2, 1, 0.010, 0.001, 0.0, SOFT),
              "row of two across, 0.01 mm": grid(1, 2, 0.010, 0.001, 1e-5, SOFT),
              "2 x 2, 0.01 mm across": grid(2, 2, 0.010, 0.001, 1e-5, SOFT)}
    out = [{"plate": name, "fetches": [fetch(env, th, pieces) for th in THETAS]}
           for name, pieces in plates.items()]
    for across in (1e-3, 3e-4):
        pieces = grid(2, 2, 0.010, 0.001, across, SOFT)
        out.append({"plate": f"2 x 2, {across * 1e3:g} mm across",
                    "fetches": [fetch(env, th, pieces) for th in (0.06, 0.07, 0.08)]})
    return out


def settings() -> list[dict[str, Any]]:
    """Check 2: tuning plates at the default, a finer step and a stiffer friction."""
    out = []
    for name, kwargs in SETTINGS.items():
        env = gym.make(ENV_ID, **kwargs)
        out.append({"setting": name, "kwargs": kwargs,
                    "fetches": [{"seed": s, **fetch(env, th, seed=s)}
                                for s, th in SEEDS_AND_ANGLES]})
    return out


SPACED_THETAS = (0.03, 0.04, 0.05, 0.06, 0.07, 0.08, 0.09, 0.10)  # [rad]


def spaced_tuning_plates(seeds: range = range(100, 140), across: float = 1e-3
                         ) -> list[dict[str, Any]]:
    """Check 3: the very soft tuning plates with their rows ``across`` [m] apart."""
    env = gym.make(ENV_ID, estimator="none")
    out = []
    for seed in seeds:
        env.reset(seed=seed)
        pieces = env.unwrapped.pieces
        if pieces[0].material.young > SOFT.young:
            continue
        spaced = two_rows(material=pieces[0].material, n=len(pieces) // 2,
                          size=pieces[0].size, spacing_along=TWO_ROWS_SPACING_ALONG,
                          spacing_across=across)
        fetches = []
        for theta in SPACED_THETAS:
            env.reset(seed=seed, options={"pieces": list(spaced)})
            _, reward, _, _, info = env.step(physical_to_action(theta, 0.4, 0.04))
            fetches.append({"theta": theta, "reward": round(float(reward), 4),
                            "fetch_rate": info["fetch_rate"],
                            "le_max": round(max(p["max_log_strain_clamp"]
                                                for p in info["pieces"]), 3)})
        out.append({"seed": seed, "n_pieces": len(spaced), "size_mm": pieces[0].size * 1e3,
                    "fetches": fetches})
    return out


LEVEL_THETAS = (0.04, 0.05, 0.07)  # [rad] a light touch, the best constant, a deep squeeze
# TwoRows-v3's round pieces are first held at 0.06-0.07 rad and its best constant is 0.07 rad
ID_LEVEL_THETAS = {"FoodFetch-TwoRows-v3": (0.05, 0.07, 0.09)}  # [rad]
SOFTEST_LEVEL = {"FoodFetch-TwoRows-v1": SOFT.young, "FoodFetch-TwoRows-v2": 0.06e6,
                 "FoodFetch-TwoRows-v3": 0.06e6}  # [Pa]
DISAGREE = 0.5  # rewards further apart than this across settings: the numerics decide


def soft_levels(env_id: str, seeds: range = range(100, 140)) -> list[dict[str, Any]]:
    """Check 4: each tuning plate of ``env_id``'s softest level at :data:`LEVEL_THETAS` under
    every setting of :data:`SETTINGS`, with the largest reward difference between settings."""
    envs = {name: gym.make(env_id, estimator="none", **kw) for name, kw in SETTINGS.items()}
    out = []
    for seed in seeds:
        envs["default"].reset(seed=seed)
        young = envs["default"].unwrapped.pieces[0].material.young
        if young > SOFTEST_LEVEL[env_id]:
            continue
        for theta in ID_LEVEL_THETAS.get(env_id, LEVEL_THETAS):
            by_setting = {name: fetch(env, theta, seed=seed) for name, env in envs.items()}
            rewards = [f["reward"] for f in by_setting.values()]
            out.append({"seed": seed, "young_mpa": young / 1e6, "theta": theta,
                        "spread": round(max(rewards) - min(rewards), 4), **by_setting})
            print(f"seed {seed} {young / 1e6:g} MPa @ {theta}: "
                  + " ".join(f"{r:+.2f}" for r in rewards), flush=True)
    return out


def summarize_levels(rows: list[dict[str, Any]]) -> dict[str, dict[str, Any]]:
    """Per clamp angle: fetches, how many settings disagree by > DISAGREE, the mean spread,
    and each setting's mean reward (sums exactly rounded, so that every Python version gives
    the same digits: 3.12's ``sum`` of floats compensates, 3.11's does not)."""
    out: dict[str, dict[str, Any]] = {}
    for theta in sorted({r["theta"] for r in rows}):
        at = [r for r in rows if r["theta"] == theta]
        n_off = sum(r["spread"] > DISAGREE for r in at)
        out[f"{theta:g}"] = {
            "fetches": len(at), "settings_disagree": n_off,
            "mean_spread": round(math.fsum(r["spread"] for r in at) / len(at), 3),
            "mean_reward": {name: round(math.fsum(r[name]["reward"] for r in at) / len(at), 3)
                            for name in SETTINGS}}
    return out


def main_levels(env_id: str, out: Path) -> int:
    data: dict[str, Any] = {"env_id": env_id,
                            "thetas": list(ID_LEVEL_THETAS.get(env_id, LEVEL_THETAS)),
                            "settings": SETTINGS, "disagree_above": DISAGREE, "meta": meta()}
    data["fetches"] = soft_levels(env_id)
    data["summary"] = summarize_levels(data["fetches"])
    write_json(out, data)
    for theta, s in data["summary"].items():
        print(f"{theta} rad: {s['settings_disagree']} of {s['fetches']} plates disagree across "
              f"settings; mean spread {s['mean_spread']}; mean rewards {s['mean_reward']}")
    return 0


def main_spaced(out: Path) -> int:
    data: dict[str, Any] = {"env_id": ENV_ID, "spacing_across_m": 1e-3, "meta": meta(),
                            "plates": spaced_tuning_plates()}
    write_json(out, data)
    for row in data["plates"]:
        print(f"seed {row['seed']}", " ".join(f"{f['theta']}: {f['reward']:+.2f}"
                                              for f in row["fetches"]))
    return 0


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--out", type=Path, default=None)
    p.add_argument("--spaced", action="store_true",
                   help="only check 3: the very soft tuning plates with rows 1 mm apart")
    p.add_argument("--levels", metavar="ID", choices=tuple(SOFTEST_LEVEL), default=None,
                   help="only check 4: the softest tuning plates of ID under every setting")
    args = p.parse_args(argv)
    warnings.filterwarnings("ignore", category=UserWarning)  # clipping notes: in the JSON
    if args.levels:
        name = f"very_soft_plates_levels_{args.levels.rsplit('-', 1)[1]}.json"
        return main_levels(args.levels, args.out or ROOT / "docs" / "data" / name)
    if args.spaced:
        return main_spaced(args.out or ROOT / "docs" / "data" / "very_soft_plates_spaced.json")
    args.out = args.out or ROOT / "docs" / "data" / "very_soft_plates.json"
    data: dict[str, Any] = {"env_id": ENV_ID, "meta": meta(), "complete": False}
    data["arrangements"] = arrangements()
    write_json(args.out, data)
    for row in data["arrangements"]:
        print(f"{row['plate']:28s}", " ".join(
            f"{f['theta']}: LE {f['le_max']:.2f} x {f['farthest_x_mm']:.0f} mm"
            for f in row["fetches"]), flush=True)
    data["settings"] = settings()
    data["complete"] = True
    write_json(args.out, data)
    for row in data["settings"]:
        print(f"{row['setting']:15s}", " ".join(
            f"seed {f['seed']} @ {f['theta']}: r {f['reward']:+.2f} LE {f['le_max']:.2f}"
            for f in row["fetches"]))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
