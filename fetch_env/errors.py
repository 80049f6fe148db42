"""Errors raised by the simulator: bad input before any work, divergence during it."""

from __future__ import annotations

import numbers
from typing import Any

import numpy as np


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


def require_finite(name: str, value: Any) -> None:
    """Reject anything but a finite real number (NaN, infinities, strings, arrays, complex, bool).

    Every range check that follows compares ``value`` with numbers: a value of another type
    would raise a bare ``TypeError`` (complex, str) or ``ValueError`` (a numpy array's
    ambiguous truth) there, so it is refused here with the package's error naming it.
    ``bool`` is refused too: ``True`` is an ``int`` but never a meant quantity.
    """
    ok = (isinstance(value, numbers.Real) and not isinstance(value, bool | np.bool_)
          and value == value and abs(value) != float("inf"))
    require(bool(ok), name, value, "a finite number")


def require_int(name: str, value: Any) -> None:
    """Reject anything but an integer (Python or numpy; ``bool`` is refused).

    A float count (``2.5``) would be truncated or would make ``np.arange`` count fractional
    steps without a word, so counts must be integers.
    """
    require(isinstance(value, numbers.Integral) and not isinstance(value, bool | np.bool_),
            name, value, "an integer")


def env_error_line(exc: BaseException) -> str:
    """The first line of an error raised while building an env, without the suffix
    gymnasium appends (" was raised from the environment creator for ... with kwargs ...")."""
    lines = str(exc).strip().splitlines()
    line = lines[0] if lines else type(exc).__name__
    return line.split(" was raised from the environment creator")[0]
