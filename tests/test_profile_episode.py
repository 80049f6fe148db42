"""The episode profiler (benchmarks/profile_episode.py): its physics steps are the fetch
profile's, phase by phase; it leaves MuJoCo and the env as it found them; and the docs table
is the committed JSON's."""

from __future__ import annotations

import importlib.util
import json
import sys
from pathlib import Path
from typing import Any

import mujoco
import numpy as np
import pytest

import fetch_env.controller as controller
import fetch_env.env as env_module
from fetch_env.controller import PHASES

ROOT = Path(__file__).resolve().parents[1]


def _profiler() -> Any:
    sys.path.insert(0, str(ROOT))
    spec = importlib.util.spec_from_file_location("profile_episode",
                                                  ROOT / "benchmarks" / "profile_episode.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_fetch_steps_are_counted_by_the_profiles_phases(monkeypatch: pytest.MonkeyPatch
                                                        ) -> None:
    pe = _profiler()
    profiles: list[Any] = []
    make = controller.make_profile

    def keep(experiment: str, *args: Any, **kwargs: Any) -> Any:
        out = make(experiment, *args, **kwargs)
        if experiment == "fetch":
            profiles.append(out)
        return out

    monkeypatch.setattr(controller, "make_profile", keep)
    originals = (mujoco.mj_step, controller.build_scene, controller._step_through,
                 env_module.run_probes)
    r = pe.profile_id("FoodFetch-Block-v1", episodes=2, seed=5000)
    assert (mujoco.mj_step, controller.build_scene, controller._step_through,
            env_module.run_probes) == originals
    assert len(profiles) == 2
    counts = sum(np.bincount(p.phase, minlength=len(PHASES)) for p in profiles) / 2
    fetch = r["stages"]["step"]["parts"]
    for code, phase in enumerate(PHASES):
        steps = fetch.get(f"physics: {phase}", {}).get("steps", 0)
        assert steps == pytest.approx(counts[code]), phase
        if counts[code]:
            assert fetch[f"physics: {phase}"]["cpu_s"] > 0, phase
    reset = r["stages"]["reset"]["parts"]
    assert reset["physics"]["steps"] > 100  # the relaxation and slip probes
    assert reset["scene build"]["cpu_s"] > 0 and reset["probe fits"]["cpu_s"] > 0
    for stage in r["stages"].values():  # the timed parts lie inside the stage: none counted twice
        assert stage["parts"]["other"]["cpu_s"] >= -1e-3, stage


def test_the_docs_table_is_the_committed_profile() -> None:
    pe = _profiler()
    data = json.loads((ROOT / "docs" / "data" / "profile_episode.json").read_text())
    text = (ROOT / "docs" / "benchmarks.md").read_text()
    assert f"{pe.BEGIN}\n{pe.table(data)}\n{pe.END}" in text
    assert set(data["results"]) == set(pe.DEFAULT_IDS)
