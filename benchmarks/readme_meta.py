"""The machine and command a README results file records (``docs/data/readme_*.json``).

Each benchmark that feeds a README table stores this beside its figures, so the table can say
where and how its numbers were made.
"""

from __future__ import annotations

import os
import platform
import shlex
import subprocess
import sys
from pathlib import Path
from typing import Any

import mujoco

ROOT = Path(__file__).resolve().parents[1]


def _cpu_model() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def _commit() -> str:
    try:
        out = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=ROOT,
                             capture_output=True, text=True, check=True)
    except (OSError, subprocess.CalledProcessError):
        return "unknown"
    return out.stdout.strip()


def meta(wall_s: float | None = None) -> dict[str, Any]:
    """Machine, software, commit, load and the command line that ran this script."""
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    script = Path(sys.argv[0]).resolve()
    argv = [script.relative_to(ROOT).as_posix() if script.is_relative_to(ROOT)
            else sys.argv[0], *sys.argv[1:]]
    return {
        "machine": f"{platform.machine()}, {os.cpu_count()} cores ({_cpu_model()})",
        "python": platform.python_version(),
        "mujoco": mujoco.__version__,
        "commit": _commit(),
        "load_average_at_start": round(load, 2),
        "command": "python " + shlex.join(argv),
        "wall_s": None if wall_s is None else round(wall_s, 1),
    }


def write_json(path: Path, data: dict[str, Any]) -> None:
    """Write atomically (a stopped run leaves the old file)."""
    import json

    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(json.dumps(data, indent=1) + "\n")
    tmp.replace(path)


def rewrite_block(path: Path, begin: str, end: str, body: str) -> None:
    """Replace what lies between the marker lines ``begin`` and ``end`` in ``path`` with
    ``body`` (atomically); refused, naming the file, where ``begin`` is missing."""
    text = path.read_text()
    head, found, rest = text.partition(begin)
    if not found:
        raise SystemExit(f"{path}: no {begin} block")
    _, _, tail = rest.partition(end)
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(f"{head}{begin}\n{body}\n{end}{tail}")
    tmp.replace(path)
