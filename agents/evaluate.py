"""Evaluate agents on the same seeded scenes: per-episode records, summaries with 95 %
intervals, regret against ``search``, CSV/JSON output and plots.

Episode ``i`` of every agent uses the scene of ``env.reset(seed=seed + i)`` and the agent is
seeded with ``seed + i`` too, so each (agent, episode) is an independent, reproducible work
item: ``workers > 1`` runs them in a process pool and gives the same numbers as one worker.
"""

from __future__ import annotations

import math
import signal
import time
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from agents.base import Agent

AGENT_NAMES: tuple[str, ...] = ("random", "study", "model-based", "search")
REFERENCE = "search"


class AgentSpecError(Exception):
    """An unknown agent name or an unusable model path (one line)."""


def make_agent(spec: str, env_id: str | None = None) -> Agent:
    """An agent from a name in ``AGENT_NAMES`` or the path of a saved SB3 model (.zip)."""
    if spec == "random":
        from agents.baselines import RandomAgent

        return RandomAgent()
    if spec == "study":
        from agents.baselines import StudyAgent

        diced = None if env_id is None else env_id.startswith("FoodFetch-Diced")
        return StudyAgent(diced=diced)
    if spec == "model-based":
        from agents.model_based import ModelBasedAgent

        return ModelBasedAgent()
    if spec == "search":
        from agents.search import SearchAgent

        return SearchAgent()
    looks_like_path = spec.endswith(".zip") or "/" in spec or Path(spec).exists()
    if not looks_like_path:
        raise AgentSpecError(f"unknown agent {spec!r}; choose from {', '.join(AGENT_NAMES)} "
                             "or give the path of a saved model (.zip)")
    from agents.sb3_agent import ModelLoadError, SB3Agent

    try:
        return SB3Agent(spec)
    except ModelLoadError as exc:
        raise AgentSpecError(str(exc)) from None


# ------------------------------------------------------------------------------ episodes
@dataclass
class Task:
    agent: str
    env_id: str
    episode: int
    seed: int
    env_kwargs: dict[str, Any] = field(default_factory=dict)
    record: bool = False  # also return the episode's transition (``--dataset``)


_ENVS: dict[tuple[str, str], Any] = {}
_AGENTS: dict[tuple[str, str], Agent] = {}
_WARM: list[bool] = []


def warm_up() -> None:
    """Compile one scene of every piece shape, once per process, before any episode.

    MuJoCo's compiler leaves last-bit differences in a flex's mass and stiffness that depend
    on which scene of that shape was compiled first in the process (found while checking
    ``--workers``); the contacts amplify them to ~1e-4 in LE.  Compiling a fixed scene of
    each shape first makes every later episode independent of the process's history, so
    any number of workers gives the same numbers.
    """
    if _WARM:
        return
    from fetch_env.layouts import SHAPES, Piece
    from fetch_env.scene import build_scene

    for shape in SHAPES:
        build_scene((Piece(shape, 0.015),))  # type: ignore[arg-type]
    _WARM.append(True)


def _env(env_id: str, env_kwargs: dict[str, Any]) -> Any:
    import gymnasium as gym

    import fetch_env  # noqa: F401  (registers the ids)

    key = (env_id, repr(sorted(env_kwargs.items())))
    if key not in _ENVS:
        _ENVS[key] = gym.make(env_id, **env_kwargs)
    return _ENVS[key]


def run_episode(task: Task) -> dict[str, Any]:
    """One fetch of one agent on the scene of ``seed``; a flat record."""
    warm_up()
    env = _env(task.env_id, task.env_kwargs)
    key = (task.agent, task.env_id)
    if key not in _AGENTS:
        _AGENTS[key] = make_agent(task.agent, task.env_id)
    agent = _AGENTS[key]
    wall = time.perf_counter()
    obs, reset_info = env.reset(seed=task.seed)
    agent.seed(task.seed)
    agent.begin_episode(env)
    action = np.asarray(agent.act(obs), np.float32)
    next_obs, reward, terminated, truncated, info = env.step(action)
    wall = time.perf_counter() - wall
    applied = info.get("action_applied", {})
    k = int(reset_info.get("probe_piece", 0))
    pieces = reset_info.get("pieces", [])
    material = pieces[k]["material"] if pieces else {}
    le = info.get("max_log_strain")
    record = {
        "agent": task.agent, "episode": task.episode, "seed": task.seed,
        "reward": float(reward), "fetch_rate": float(info.get("fetch_rate", 0.0)),
        "is_success": bool(info.get("is_success", False)),
        "max_log_strain": float(le) if le is not None else math.nan,
        "time_per_fetch": float(info.get("episode_time", math.nan)),
        "reward_fetch": float(info.get("reward_fetch", 0.0)),
        "reward_deformation": float(info.get("reward_deformation", 0.0)),
        "theta_d": float(applied.get("theta_d", math.nan)),
        "omega": float(applied.get("omega", math.nan)),
        "lift_speed": float(applied.get("lift_speed", math.nan)),
        "n_pieces": len(pieces),
        "young": float(material.get("young", math.nan)),
        "true_K1": float(reset_info.get("true_params", {}).get("K1", math.nan)),
        "diverged": "error" in info, "wall_s": wall,
    }
    if task.record:  # the data of a Minari episode, written by the parent in seed order
        from agents.datasets import transition

        record["transition"] = transition(obs, reset_info, action, next_obs, float(reward),
                                          bool(terminated), bool(truncated), info)
    return record


def _init_worker() -> None:
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the parent handles Ctrl-C
    try:
        import torch

        torch.set_num_threads(1)
    except ImportError:
        pass


def run_tasks(tasks: Sequence[Task], workers: int = 1,
              on_result: Callable[[dict[str, Any]], None] | None = None) -> list[dict[str, Any]]:
    """Run the tasks (in a pool when ``workers > 1``); results in task order.

    Ctrl-C stops the run: what finished is returned, and the exception is re-raised after
    ``on_result`` has seen every finished record (the caller writes them).
    """
    done: dict[int, dict[str, Any]] = {}

    def collect(items: Iterable[tuple[int, dict[str, Any]]]) -> None:
        for i, rec in items:
            done[i] = rec
            if on_result is not None:
                on_result(rec)

    interrupted: BaseException | None = None
    workers = min(workers, len(tasks))  # an idle worker would only cost its start-up
    if workers <= 1:
        try:
            collect((i, run_episode(t)) for i, t in enumerate(tasks))
        except KeyboardInterrupt as exc:
            interrupted = exc
    else:
        import multiprocessing as mp

        ctx = mp.get_context("spawn")  # a clean MuJoCo/torch state per worker
        pool = ctx.Pool(workers, initializer=_init_worker)
        try:
            collect(pool.imap_unordered(_indexed, list(enumerate(tasks)), chunksize=1))
            pool.close()
        except KeyboardInterrupt as exc:
            interrupted = exc
            pool.terminate()
        finally:
            pool.join()
    results = [done[i] for i in sorted(done)]
    if interrupted is not None:
        raise EvaluationInterrupted(results) from interrupted
    return results


class EvaluationInterrupted(Exception):
    def __init__(self, results: list[dict[str, Any]]) -> None:
        super().__init__("interrupted")
        self.results = results


def _indexed(item: tuple[int, Task]) -> tuple[int, dict[str, Any]]:
    i, task = item
    return i, run_episode(task)


# ------------------------------------------------------------------------------ statistics
def mean_ci(x: Sequence[float], level: float = 0.95) -> tuple[float, float, float]:
    """Mean and Student-t interval (NaNs dropped); one value gives a zero-width interval."""
    a = np.asarray([v for v in x if math.isfinite(v)], dtype=float)
    if a.size == 0:
        return math.nan, math.nan, math.nan
    m = float(a.mean())
    if a.size == 1:
        return m, m, m
    from scipy import stats

    h = float(stats.t.ppf(0.5 + level / 2, a.size - 1) * a.std(ddof=1) / math.sqrt(a.size))
    return m, m - h, m + h


def wilson(k: int, n: int, z: float = 1.959964) -> tuple[float, float]:
    """Wilson score interval of a proportion k / n."""
    if n == 0:
        return math.nan, math.nan
    p = k / n
    den = 1 + z * z / n
    centre = (p + z * z / (2 * n)) / den
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / den
    return max(0.0, centre - half), min(1.0, centre + half)


def summarize(records: Sequence[dict[str, Any]], agents: Sequence[str]) -> dict[str, Any]:
    """Per-agent summary with 95 % intervals; regret paired on the seeds ``search`` ran."""
    by_agent: dict[str, list[dict[str, Any]]] = {a: [] for a in agents}
    for r in records:
        by_agent.setdefault(r["agent"], []).append(r)
    ref = {r["seed"]: r["reward"] for r in by_agent.get(REFERENCE, [])}
    out: dict[str, Any] = {}
    for name in agents:
        recs = sorted(by_agent[name], key=lambda r: r["episode"])
        n = len(recs)
        if n == 0:
            out[name] = {"episodes": 0}
            continue
        s: dict[str, Any] = {"episodes": n}
        for key, col in (("reward", "reward"), ("fetch_rate", "fetch_rate"),
                         ("max_log_strain", "max_log_strain"),
                         ("time_per_fetch", "time_per_fetch")):
            m, lo, hi = mean_ci([r[col] for r in recs])
            s[f"{key}_mean"], s[f"{key}_ci95"] = m, [lo, hi]
        les = [r["max_log_strain"] for r in recs if math.isfinite(r["max_log_strain"])]
        s["max_log_strain_max"] = max(les) if les else math.nan
        k = sum(bool(r["is_success"]) for r in recs)
        s["success_rate"], s["success_rate_ci95"] = k / n, list(wilson(k, n))
        s["diverged"] = sum(bool(r["diverged"]) for r in recs)
        s["theta_d_mean"] = float(np.mean([r["theta_d"] for r in recs]))
        s["wall_s_mean"] = float(np.mean([r["wall_s"] for r in recs]))
        paired = [ref[r["seed"]] - r["reward"] for r in recs if r["seed"] in ref]
        if paired:
            m, lo, hi = mean_ci(paired)
            s["regret_mean"], s["regret_ci95"], s["regret_episodes"] = m, [lo, hi], len(paired)
        out[name] = s
    return out


# ------------------------------------------------------------------------------ output
def _fmt(m: float, ci: Sequence[float], digits: int = 3) -> str:
    if not math.isfinite(m):
        return "-"
    half = (ci[1] - ci[0]) / 2 if all(math.isfinite(c) for c in ci) else math.nan
    return f"{m:.{digits}f} ± {half:.{digits}f}" if math.isfinite(half) else f"{m:.{digits}f}"


TABLE_COLUMNS: tuple[tuple[str, str], ...] = (
    ("reward", "reward"), ("fetch rate", "fetch_rate"), ("success", "success_rate"),
    ("mean LE", "max_log_strain"), ("max LE", "max_log_strain_max"),
    ("time/fetch [s]", "time_per_fetch"), ("regret", "regret"))


def format_table(summary: dict[str, Any], markdown: bool = False) -> str:
    """One row per agent: mean ± half-width of the 95 % interval."""
    rows = [["agent", "n", *[c for c, _ in TABLE_COLUMNS]]]
    for name, s in summary.items():
        if not s.get("episodes"):
            rows.append([name, "0", *["-"] * len(TABLE_COLUMNS)])
            continue
        row = [name, str(s["episodes"])]
        for _, key in TABLE_COLUMNS:
            if key == "success_rate":  # Wilson: asymmetric, so the interval itself
                lo, hi = s["success_rate_ci95"]
                row.append(f"{s['success_rate']:.2f} [{lo:.2f}, {hi:.2f}]")
            elif key == "max_log_strain_max":
                row.append(f"{s[key]:.3f}" if math.isfinite(s[key]) else "-")
            elif key == "regret":
                row.append(_fmt(s["regret_mean"], s["regret_ci95"]) +
                           (f" (n={s['regret_episodes']})"
                            if s["regret_episodes"] != s["episodes"] else "")
                           if "regret_mean" in s else "-")
            elif key == "time_per_fetch":
                row.append(_fmt(s[f"{key}_mean"], s[f"{key}_ci95"], 2))
            else:
                row.append(_fmt(s[f"{key}_mean"], s[f"{key}_ci95"]))
        rows.append(row)
    if markdown:
        lines = ["| " + " | ".join(rows[0]) + " |", "|" + "---|" * len(rows[0])]
        lines += ["| " + " | ".join(r) + " |" for r in rows[1:]]
        return "\n".join(lines)
    widths = [max(len(r[i]) for r in rows) for i in range(len(rows[0]))]
    return "\n".join("  ".join(c.ljust(w) for c, w in zip(r, widths, strict=True)).rstrip()
                     for r in rows)


CSV_FIELDS: tuple[str, ...] = (
    "agent", "episode", "seed", "reward", "fetch_rate", "is_success", "max_log_strain",
    "time_per_fetch", "reward_fetch", "reward_deformation", "theta_d", "omega", "lift_speed",
    "n_pieces", "young", "true_K1", "diverged", "wall_s")


def write_csv(path: Path, records: Sequence[dict[str, Any]]) -> None:
    import csv
    import os

    tmp = path.with_name(path.name + ".part")
    with open(tmp, "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(CSV_FIELDS), extrasaction="ignore")
        w.writeheader()
        for r in sorted(records, key=lambda r: (r["agent"], r["episode"])):
            w.writerow(r)
    os.replace(tmp, path)


def write_plots(directory: Path, summary: dict[str, Any],
                records: Sequence[dict[str, Any]], env_id: str) -> list[Path]:
    """reward.png and fetch_rate.png (mean and 95 % interval per agent) and theta_vs_stiffness.png
    (the chosen theta_d against the probed piece's Young's modulus)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    directory.mkdir(parents=True, exist_ok=True)
    names = [n for n, s in summary.items() if s.get("episodes")]
    out: list[Path] = []
    for key, label in (("reward", "mean reward"), ("fetch_rate", "mean fetch rate")):
        fig, ax = plt.subplots(figsize=(1.4 * len(names) + 2, 3.2))
        means = [summary[n][f"{key}_mean"] for n in names]
        err = np.array([[summary[n][f"{key}_mean"] - summary[n][f"{key}_ci95"][0],
                         summary[n][f"{key}_ci95"][1] - summary[n][f"{key}_mean"]]
                        for n in names]).T
        ax.bar(range(len(names)), means, yerr=err, capsize=4, color="tab:blue", alpha=0.8)
        ax.set_xticks(range(len(names)), [_short(n) for n in names], rotation=15)
        ax.set_ylabel(label)
        ax.set_title(f"{env_id}: {label} (95 % interval)")
        fig.tight_layout()
        p = directory / f"{key}.png"
        fig.savefig(p, dpi=110)
        plt.close(fig)
        out.append(p)
    fig, ax = plt.subplots(figsize=(5.5, 3.8))
    for n in names:
        rs = [r for r in records if r["agent"] == n]
        ax.scatter([r["young"] for r in rs], [r["theta_d"] for r in rs], s=12, label=_short(n),
                   alpha=0.7)
    ax.set_xscale("log")
    ax.set_xlabel("probed piece's Young's modulus E_0 [Pa]")
    ax.set_ylabel("theta_d applied [rad]")
    ax.set_title(f"{env_id}: chosen clamp angle against stiffness")
    ax.legend(fontsize=8)
    fig.tight_layout()
    p = directory / "theta_vs_stiffness.png"
    fig.savefig(p, dpi=110)
    plt.close(fig)
    out.append(p)
    return out


def _short(name: str) -> str:
    return name if len(name) <= 18 else "…" + name[-17:]


def record_videos(directory: Path, agents: Sequence[str], env_id: str, seed: int,
                  env_kwargs: dict[str, Any]) -> list[Path]:
    """One MP4 (GIF without ffmpeg) per agent of the first evaluation scene."""
    import gymnasium as gym

    import fetch_env  # noqa: F401

    directory.mkdir(parents=True, exist_ok=True)
    out = []
    env = gym.make(env_id, render_mode="rgb_array_list", **env_kwargs)
    try:
        for name in agents:
            agent = make_agent(name, env_id)
            obs, _ = env.reset(seed=seed)
            agent.seed(seed)
            agent.begin_episode(env)
            env.step(agent.act(obs))
            frames = env.render()
            stem = "".join(c if c.isalnum() or c in "-_" else "_" for c in _short(name))
            out.append(_save_frames(directory / stem, frames, env.metadata["render_fps"]))
    finally:
        env.close()
    return out


def _save_frames(stem: Path, frames: list[np.ndarray], fps: int) -> Path:
    import imageio.v2 as imageio

    try:
        path = stem.with_suffix(".mp4")
        imageio.mimsave(path, frames, fps=fps)
    except Exception:  # no ffmpeg backend: a GIF still shows the fetch
        path = stem.with_suffix(".gif")
        imageio.mimsave(path, frames, duration=1000 / fps)
    return path
