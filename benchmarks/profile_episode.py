"""Where an episode's time goes, per environment id: scene builds, the probes' physics and
fits, each fetch phase's physics, and the Python around them.

Each episode is a ``reset(seed=S + i)`` and one random action (seeded), the default env
settings, as a training run sees them.  The figures are the main thread's CPU time
(``time.thread_time``), so a machine shared with other jobs changes them little; shares
within one run are what to compare.  Three places are timed by wrapping them for the run:

* ``fetch_env.controller.build_scene``: every MuJoCo scene compiled, by stage (the probes'
  and the fetch's are all compiled in the reset, so that bad pieces fail there);
* ``mujoco.mj_step``: the physics, by stage, and in the fetch by phase (``settle``,
  ``clamp``, ``hold``, ``lift``, ``air``; the phase of each step is the fetch profile's);
* the probes' fits: ``cpu_fits`` that ``fetch_env.probes.run_probes`` reports.

"other" is the rest of a stage: the step loop's own Python (the servo commands, the Prony
relaxation forces, the sensors and strain), the outcomes, the observation and the reward.

Run: python benchmarks/profile_episode.py [--ids ID ...] [--episodes 6] [--seed 5000]
       [--json docs/data/profile_episode.json]
"""

from __future__ import annotations

import argparse
import contextlib
import json
import sys
import time
from collections import defaultdict
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import gymnasium as gym
import mujoco

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import fetch_env  # noqa: F401  (registers the ids)
import fetch_env.controller as controller
import fetch_env.env as env_module
from benchmarks.readme_meta import meta, rewrite_block, write_json
from fetch_env.controller import PHASES

ROOT = Path(__file__).resolve().parents[1]
DEFAULT_IDS = ("FoodFetch-Block-v1", "FoodFetch-Row-v1", "FoodFetch-TwoRows-v1",
               "FoodFetch-Diced-v1")


class Ledger:
    """CPU seconds and call counts by (stage, part); the stage is set by the caller, the
    fetch phase of each physics step from the profile the step loop was given."""

    def __init__(self) -> None:
        self.cpu: dict[tuple[str, str], float] = defaultdict(float)
        self.calls: dict[tuple[str, str], int] = defaultdict(int)
        self.stage = "reset"
        self.phases: Any = None  # the running fetch's per-step phase codes, or None
        self.step_index = 0

    def add(self, part: str, seconds: float) -> None:
        self.cpu[self.stage, part] += seconds
        self.calls[self.stage, part] += 1


@contextlib.contextmanager
def instrumented(ledger: Ledger) -> Iterator[None]:
    """Wrap scene builds, ``mj_step``, the step loop and the probes for as long as the
    context is open, and put the originals back after."""
    build, step, through, run_probes = (controller.build_scene, mujoco.mj_step,
                                        controller._step_through, env_module.run_probes)

    def timed_build(*args: Any, **kwargs: Any) -> Any:
        t = time.thread_time()
        try:
            return build(*args, **kwargs)
        finally:
            ledger.add("scene build", time.thread_time() - t)

    def timed_step(m: mujoco.MjModel, d: mujoco.MjData) -> None:
        t = time.thread_time()
        step(m, d)
        dt = time.thread_time() - t
        if ledger.phases is None:
            ledger.add("physics", dt)
        else:
            ledger.add(f"physics: {PHASES[ledger.phases[ledger.step_index]]}", dt)
            ledger.step_index += 1

    def traced_loop(scene: Any, d: Any, profile: Any, *args: Any) -> Any:
        fetch = ledger.stage == "step"
        ledger.phases, ledger.step_index = (profile.phase if fetch else None), 0
        try:
            return through(scene, d, profile, *args)
        finally:
            ledger.phases = None

    def probes_with_fits(*args: Any, **kwargs: Any) -> Any:
        out = run_probes(*args, **kwargs)
        ledger.add("probe fits", float(out.details.get("cpu_fits", 0.0)))
        return out

    patches: list[tuple[Any, str, Callable[..., Any]]] = [
        (controller, "build_scene", timed_build), (mujoco, "mj_step", timed_step),
        (controller, "_step_through", traced_loop),
        (env_module, "run_probes", probes_with_fits)]  # (the env imports it by name)
    originals = [(obj, name, getattr(obj, name)) for obj, name, _ in patches]
    try:
        for obj, name, new in patches:
            setattr(obj, name, new)
        yield
    finally:
        for obj, name, old in originals:
            setattr(obj, name, old)


def profile_id(env_id: str, episodes: int, seed: int) -> dict[str, Any]:
    """CPU seconds per episode by stage and part, over ``episodes`` seeded episodes."""
    env = gym.make(env_id)
    env.action_space.seed(seed)
    ledger, total = Ledger(), defaultdict(float)
    steps = defaultdict(int)
    with instrumented(ledger):
        for i in range(episodes):
            for stage in ("reset", "step"):
                ledger.stage = stage
                t = time.thread_time()
                if stage == "reset":
                    env.reset(seed=seed + i)
                else:
                    env.step(env.action_space.sample())
                total[stage] += time.thread_time() - t
    env.close()
    for (stage, part), n in ledger.calls.items():
        if part.startswith("physics"):
            steps[stage, part] = n
    return _summary(ledger, total, steps, episodes)


def _summary(ledger: Ledger, total: dict[str, float], steps: dict[tuple[str, str], int],
             episodes: int) -> dict[str, Any]:
    out: dict[str, Any] = {"episodes": episodes,
                           "cpu_s_per_episode": (total["reset"] + total["step"]) / episodes,
                           "stages": {}}
    for stage in ("reset", "step"):
        parts = {part: cpu / episodes for (s, part), cpu in ledger.cpu.items() if s == stage}
        parts["other"] = total[stage] / episodes - sum(parts.values())
        out["stages"][stage] = {
            "cpu_s": total[stage] / episodes,
            "parts": {p: {"cpu_s": v, "steps": steps.get((stage, p), 0) / episodes}
                      for p, v in sorted(parts.items(), key=lambda kv: -kv[1])}}
    return out


RESET_PARTS = ("physics", "probe fits", "scene build", "other")
FETCH_PARTS = (*(f"physics: {ph}" for ph in PHASES if ph != "slide"), "other")
DOCS = ROOT / "docs" / "benchmarks.md"
BEGIN = "<!-- profile-table: generated by benchmarks/profile_episode.py --docs, do not edit -->"
END = "<!-- /profile-table -->"


def table(data: dict[str, Any]) -> str:
    """One row per id: CPU ms per episode and each part's share of it, the reset's parts
    then the fetch's (``-`` where a part took no time); the machine and command below."""
    heads = ["reset: probe physics", "probe fits", "scene builds", "other",
             *(f"fetch: {ph}" if ph == "settle" else ph for ph in PHASES if ph != "slide"),
             "other"]
    lines = ["| id | CPU ms / episode | " + " | ".join(heads) + " |",
             "|---|---|" + "---|" * len(heads)]
    for env_id, r in data["results"].items():
        whole = r["cpu_s_per_episode"]
        cells = []
        for stage, parts in (("reset", RESET_PARTS), ("step", FETCH_PARTS)):
            got = r["stages"][stage]["parts"]
            cells += [f"{got[p]['cpu_s'] / whole:.0%}" if p in got else "-" for p in parts]
        lines.append(f"| {env_id.removeprefix('FoodFetch-')} | {1e3 * whole:.0f} | "
                     + " | ".join(cells) + " |")
    m = data["meta"]
    lines.append("")
    lines.append(f"{m['machine']}, at {m['commit']}; {data['episodes']} episodes per id from "
                 f"seed {data['seed']}, random actions, main-thread CPU time: "
                 f"`{m['command']}`")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--ids", nargs="+", default=list(DEFAULT_IDS))
    p.add_argument("--episodes", type=int, default=6)
    p.add_argument("--seed", type=int, default=5000)
    p.add_argument("--json", type=Path, default=None, metavar="FILE",
                   help="also write the figures here")
    p.add_argument("--docs", type=Path, default=None, metavar="FILE",
                   help="only rewrite docs/benchmarks.md's table from FILE (a --json output)")
    args = p.parse_args(argv)
    if args.docs is not None:
        try:
            text = table(json.loads(args.docs.read_text()))
        except (OSError, ValueError, KeyError, TypeError) as exc:
            p.error(f"--docs {args.docs}: not a profile written by --json ({exc})")
        rewrite_block(DOCS, BEGIN, END, text)
        return 0
    unknown = [i for i in args.ids if i not in gym.registry]
    if unknown:
        p.error(f"--ids: {unknown[0]!r} is not a registered id")
    if args.episodes < 1:
        p.error(f"--episodes must be >= 1, got {args.episodes}")
    data = {"meta": meta(), "seed": args.seed, "episodes": args.episodes,
            "results": {env_id: profile_id(env_id, args.episodes, args.seed)
                        for env_id in args.ids}}
    print(table(data))
    if args.json is not None:
        write_json(args.json, data)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
