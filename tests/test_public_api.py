"""Each package's public API is its ``__all__``: every name there imports, the list is sorted
and has no repeats, and every public name the package binds (other than its modules) is in it."""

from __future__ import annotations
import __future__

import importlib
import subprocess
import sys
import types
from pathlib import Path

import pytest

PACKAGES = ("estimators", "fetch_env")
ROOT = Path(__file__).resolve().parents[1]


def _public_names(module: types.ModuleType) -> set[str]:
    """Names the package binds that do not start with ``_``, less submodules and
    ``from __future__`` features."""
    return {
        name
        for name, value in vars(module).items()
        if not name.startswith("_")
        and not isinstance(value, types.ModuleType)
        and not isinstance(value, __future__._Feature)
    }


@pytest.mark.parametrize("package", PACKAGES)
def test_all_names_import(package: str) -> None:
    module = importlib.import_module(package)
    for name in module.__all__:
        assert hasattr(module, name), f"{package}.__all__ lists {name!r}, which is not there"


@pytest.mark.parametrize("package", PACKAGES)
def test_all_sorted_without_repeats(package: str) -> None:
    names = list(importlib.import_module(package).__all__)
    assert names == sorted(names)
    assert len(names) == len(set(names))


@pytest.mark.parametrize("package", PACKAGES)
def test_all_complete(package: str) -> None:
    module = importlib.import_module(package)
    assert _public_names(module) == set(module.__all__)


def test_star_import_of_fetch_env_leaves_mujoco_unloaded() -> None:
    """``from fetch_env import *`` stays light: MuJoCo is loaded only when an env is made."""
    code = "from fetch_env import *; import sys; print('mujoco' in sys.modules, ENV_IDS)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout
    assert out.startswith("False ")


def test_no_estimators_module_loads_the_simulator() -> None:
    """Every module of ``estimators`` (the code that reads a robot's logs) imports without
    MuJoCo, the simulator or the agents."""
    modules = sorted(p.stem for p in (ROOT / "estimators").glob("*.py") if p.stem != "__init__")
    code = (f"import sys, importlib; [importlib.import_module('estimators.' + m) for m in "
            f"{modules!r}]; print(sorted({{m.split('.')[0] for m in sys.modules}} & "
            "{'mujoco', 'fetch_env', 'agents'}))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True, cwd=ROOT).stdout
    assert "slip_level" in modules and out.strip() == "[]"


def test_estimators_star_import_gives_the_estimators() -> None:
    namespace: dict[str, object] = {}
    exec("from estimators import *", namespace)  # the public API as a user sees it
    for name in ("estimate_three_step", "estimate_full_fit", "estimate_from_hold",
                 "estimate_friction", "ClampGeometry", "SLSParams", "EstimationError"):
        assert name in namespace


@pytest.mark.parametrize("package", ["agents", "agents.cli", "agents.study"])
def test_agents_packages_list_their_api(package: str) -> None:
    """Every name in ``__all__`` imports, sorted without repeats."""
    module = importlib.import_module(package)
    names = list(module.__all__)
    assert names == sorted(names) and len(names) == len(set(names))
    for name in names:
        assert getattr(module, name) is not None, f"{package}.{name}"


def test_import_agents_stays_light() -> None:
    """``import agents`` loads neither MuJoCo nor torch until a name is used."""
    code = ("import sys, agents; print('mujoco' in sys.modules, 'torch' in sys.modules); "
            "agents.StudyAgent; print('mujoco' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout.split()
    assert out == ["False", "False", "True"]
