"""Baselines without a model: ``random`` (uniform actions) and ``study`` (the study's fixed
clamp settings: 0.045 rad for blocks, 0.085 rad for diced food, 0.1 rad/s, 5 mm/s)."""

from __future__ import annotations

from typing import Any

import numpy as np

from agents.base import Agent
from fetch_env.env import decode_observation, physical_to_action

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
