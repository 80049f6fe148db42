"""The agents that choose the clamp angle and speeds, their training and evaluation.

The agents share :class:`agents.base.Agent` (``act(obs) -> action``); :func:`make_agent` builds
one by name (``random``, ``study``, ``size-only``, ``model-based``, ``search``) or from a
model saved by ``food-fetch train``.  Subpackages: :mod:`agents.cli` (the ``food-fetch``
command) and :mod:`agents.study` (the study's reproductions).  Names are imported on first use, so
``import agents`` stays light (no MuJoCo, no torch).
"""

from __future__ import annotations

import importlib
from typing import Any

# public name -> the module that defines it
_EXPORTS: dict[str, str] = {
    "Agent": "agents.base",
    "ModelBasedAgent": "agents.model_based",
    "ModelBasedConfig": "agents.model_based",
    "RandomAgent": "agents.baselines",
    "SB3Agent": "agents.sb3_agent",
    "SearchAgent": "agents.search",
    "SizeOnlyAgent": "agents.baselines",
    "StudyAgent": "agents.baselines",
    "make_agent": "agents.evaluate",
}

__all__ = sorted(_EXPORTS)


def __getattr__(name: str) -> Any:
    if name not in _EXPORTS:
        raise AttributeError(f"module 'agents' has no attribute {name!r}")
    value = getattr(importlib.import_module(_EXPORTS[name]), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
