"""Errors raised by the simulator: bad input before any work, divergence during it."""

from __future__ import annotations

from typing import Any


class InvalidParameterError(ValueError):
    """A parameter is out of its valid range; raised before any simulation starts.

    The message always names the parameter and the offending value.
    """


class SimulationDivergedError(RuntimeError):
    """The physics diverged (NaN, or MuJoCo flagged a bad acceleration) during a run.

    Carries the scene description and the action that caused it so that the failure can be
    reproduced exactly (``scene`` and ``action`` are plain JSON-able dicts).
    """

    def __init__(self, message: str, scene: dict[str, Any], action: dict[str, Any]) -> None:
        super().__init__(message)
        self.scene = scene
        self.action = action

    def one_line(self) -> str:
        """A single line for the command line: what diverged and with which action."""
        act = ", ".join(f"{k}={v:g}" if isinstance(v, float) else f"{k}={v}"
                        for k, v in self.action.items())
        return f"simulation diverged: {self.args[0]} (action: {act})"


def require(condition: bool, name: str, value: Any, expectation: str) -> None:
    """Raise :class:`InvalidParameterError` naming ``name`` and ``value`` unless ``condition``."""
    if not condition:
        raise InvalidParameterError(f"{name} must be {expectation}, got {value!r}")


def require_finite(name: str, value: float) -> None:
    """Reject NaN and infinities (``float('nan') > 0`` is False, but be explicit)."""
    try:
        ok = value == value and abs(value) != float("inf")
    except TypeError:
        ok = False
    require(ok, name, value, "a finite number")
