"""The agent interface every baseline, search and trained policy implements.

An agent maps one observation of a ``FoodFetch-*`` environment (a contextual bandit: one
fetch per episode) to one action in ``[-1, 1]^3``.  It has a ``name`` (the key in the
evaluation tables) and is seedable, so that a seeded evaluation is reproducible.  Agents
that need the scene itself (the per-scene search) override :meth:`Agent.begin_episode`,
which the evaluation loop calls after every ``reset`` with the environment.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from typing import Any

import numpy as np


class Agent(ABC):
    """An observation in, an action out; a name; seedable."""

    name: str = "agent"

    def __init__(self) -> None:
        self.rng = np.random.default_rng()

    def seed(self, seed: int | None = None) -> None:
        """Seed the agent's own randomness (a no-op for deterministic agents)."""
        self.rng = np.random.default_rng(seed)

    def begin_episode(self, env: Any) -> None:  # noqa: B027 (optional hook)
        """Called after each ``env.reset``; agents that need the scene keep ``env``."""

    @abstractmethod
    def act(self, obs: np.ndarray) -> np.ndarray:
        """The action (float32, shape (3,), in [-1, 1]) for this observation."""

    def describe(self) -> dict[str, Any]:
        """Settings worth recording next to results (JSON-serialisable)."""
        return {"name": self.name}

    def __repr__(self) -> str:
        return f"{type(self).__name__}(name={self.name!r})"
