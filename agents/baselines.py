"""Baselines without a food model: ``random`` (uniform actions), ``study`` (the study's fixed
clamp settings: 0.045 rad for blocks, 0.085 rad for diced food, 0.1 rad/s, 5 mm/s) and
``size-only`` (a squeeze sized from the camera's width and height alone, the ablation that
shows what the probes' estimates add)."""

from __future__ import annotations

from typing import Any

import numpy as np

from agents.base import Agent
from agents.model_based import clamp_angle
from fetch_env.env import ACTION_RANGES, decode_observation, physical_to_action
from fetch_env.scene import Geometry

STUDY_THETA_BLOCK = 0.045  # [rad] the study's clamp angle for blocks and rows
STUDY_THETA_DICED = 0.085  # [rad] the study's clamp angle for diced food
STUDY_OMEGA = 0.1  # [rad/s]
STUDY_LIFT_SPEED = 0.005  # [m/s]


class RandomAgent(Agent):
    """Uniform actions in [-1, 1]^3 from the agent's own seeded generator."""

    name = "random"

    def act(self, obs: np.ndarray) -> np.ndarray:
        return self.rng.uniform(-1.0, 1.0, size=3).astype(np.float32)


def looks_diced(obs: np.ndarray) -> bool:
    """What the camera tells: several small pieces (the diced layout's 7-10 mm dice)."""
    d = decode_observation(obs)
    return d["n_pieces"] >= 4 and d["mean_size"] <= 0.0105


class StudyAgent(Agent):
    """The study's fixed settings; diced food is recognised from the camera features
    (or forced with ``diced=True/False``, e.g. from the environment id)."""

    name = "study"

    def __init__(self, diced: bool | None = None) -> None:
        super().__init__()
        self.diced = diced

    def act(self, obs: np.ndarray) -> np.ndarray:
        diced = looks_diced(obs) if self.diced is None else self.diced
        theta = STUDY_THETA_DICED if diced else STUDY_THETA_BLOCK
        return physical_to_action(theta, STUDY_OMEGA, STUDY_LIFT_SPEED)

    def describe(self) -> dict[str, Any]:
        return {"name": self.name, "theta_block": STUDY_THETA_BLOCK,
                "theta_diced": STUDY_THETA_DICED, "omega": STUDY_OMEGA,
                "lift_speed": STUDY_LIFT_SPEED}


class SizeOnlyAgent(Agent):
    """A squeeze of ``eps`` of the span along the clamp, at least ``dx_min`` a face, at the
    fastest clamp and lift: the camera's sizes only, no food property.

    With the geometry of :mod:`agents.model_based` (each face presses ``dx = L theta_d -
    gap`` into the food, ``L`` the hinge's height over the food's mid-height), ``theta_d =
    clamp_angle(geometry, height, max(eps w / 2, dx_min))``.  The band (12-15 % of the
    width, 0.7 mm) is read off the FoodFetch-Block-v1 tuning sweep (seeds 100-139,
    ``benchmarks/theta_sweep.py``): every piece there, whatever its stiffness and friction,
    is held and spared by a squeeze in it, because the closing faces' V holds a piece that
    slips and the -v1 damage is a strain.
    """

    name = "size-only"

    def __init__(self, eps: float = 0.135, dx_min: float = 0.0007,
                 geometry: Geometry | None = None) -> None:
        super().__init__()
        self.eps, self.dx_min = eps, dx_min
        self.geometry = geometry or Geometry()

    def act(self, obs: np.ndarray) -> np.ndarray:
        d = decode_observation(obs)
        width = float(d["span_along"]) if d["span_along"] > 0 else float(d["mean_size"])
        theta = clamp_angle(self.geometry, float(d["max_height"]),
                            max(self.eps * width / 2, self.dx_min))
        lo, hi = ACTION_RANGES["theta_d"]
        return physical_to_action(float(np.clip(theta, lo, hi)), ACTION_RANGES["omega"][1],
                                  ACTION_RANGES["lift_speed"][1])

    def describe(self) -> dict[str, Any]:
        return {"name": self.name, "eps": self.eps, "dx_min": self.dx_min,
                "omega": ACTION_RANGES["omega"][1],
                "lift_speed": ACTION_RANGES["lift_speed"][1]}
