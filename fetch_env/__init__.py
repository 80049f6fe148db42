"""food-fetch: MuJoCo simulator and Gymnasium environments of a two-half-spoon feeding robot.

Importing the package registers the environments (string entry points, so MuJoCo is loaded
only when an env is made)::

    import gymnasium as gym
    import fetch_env  # noqa: F401  (or gym.make("fetch_env:FoodFetch-Block-v0"))
    env = gym.make("FoodFetch-Block-v0", estimator="oracle")

The package itself exports only :data:`ENV_IDS` and the typed errors and warning a caller
catches or filters (``InvalidParameterError``, ``SimulationDivergedError``,
``ParameterClippedWarning``: a value clipped, capped or replaced, see
:mod:`fetch_env.clipping`), so that importing it stays light; the library lives in its
modules: :mod:`fetch_env.env` (the environments and their action and
observation helpers), :mod:`fetch_env.controller` (``FetchSimulator``, ``FetchAction``: the
fetch and the probe experiments with their traces), :mod:`fetch_env.scene` (``Geometry``,
``build_scene``), :mod:`fetch_env.layouts` and :mod:`fetch_env.materials` (pieces and
foods), :mod:`fetch_env.probes` (the reset probes) and :mod:`fetch_env.errors`.
"""

from __future__ import annotations

import os as _os

# Headless machines: MuJoCo's default GLFW backend aborts the process without a display, so
# offscreen rendering uses EGL unless the user chose a backend (read when mujoco is imported).
if not _os.environ.get("DISPLAY") and not _os.environ.get("WAYLAND_DISPLAY"):
    _os.environ.setdefault("MUJOCO_GL", "egl")

from gymnasium.envs.registration import register as _register
from gymnasium.envs.registration import registry as _registry

from fetch_env.errors import (
    InvalidParameterError,
    ParameterClippedWarning,
    SimulationDivergedError,
)

__all__ = ["ENV_IDS", "InvalidParameterError", "ParameterClippedWarning",
           "SimulationDivergedError"]

# id -> entry point; every id is one fetch per episode (docstrings in fetch_env/env.py).
ENV_IDS: dict[str, str] = {
    "FoodFetch-Block-v0": "fetch_env.env:FoodFetchBlockEnv",
    "FoodFetch-Row-v0": "fetch_env.env:FoodFetchRowEnv",
    "FoodFetch-TwoRows-v0": "fetch_env.env:FoodFetchTwoRowsEnv",
    "FoodFetch-Diced-v0": "fetch_env.env:FoodFetchDicedEnv",
    "FoodFetch-Block-v1": "fetch_env.env_v1:FoodFetchBlockV1Env",
    "FoodFetch-Row-v1": "fetch_env.env_v1:FoodFetchRowV1Env",
    "FoodFetch-TwoRows-v1": "fetch_env.env_v1:FoodFetchTwoRowsV1Env",
    "FoodFetch-Diced-v1": "fetch_env.env_v1:FoodFetchDicedV1Env",
    "FoodFetch-Row-v2": "fetch_env.env_v2:FoodFetchRowV2Env",
    "FoodFetch-TwoRows-v2": "fetch_env.env_v2:FoodFetchTwoRowsV2Env",
    "FoodFetch-TwoRows-v3": "fetch_env.env_v3:FoodFetchTwoRowsV3Env",
}

for _id, _entry in ENV_IDS.items():
    if _id not in _registry:  # re-importing (e.g. in a forked worker) must not warn
        _register(id=_id, entry_point=_entry, disable_env_checker=False)
