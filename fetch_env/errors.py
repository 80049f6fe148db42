"""Errors raised by the simulator: bad input before any work, divergence during it; and the
warning category of a value that was clipped, capped or replaced before use."""

from __future__ import annotations

import inspect
import numbers
from collections.abc import Callable, Mapping
from typing import Any

import numpy as np


class InvalidParameterError(ValueError):
    """A parameter is out of its valid range; raised before any simulation starts.

    The message always names the parameter and the offending value.
    """


class ParameterClippedWarning(UserWarning):
    """A value was clipped, capped or replaced before it was used (never silently).

    The message names the value, what was given, what was used and why.  The same change is
    also in the results: an environment's ``info["clipped"]``, the command line's text output
    and its JSON ``"clipped"`` (``fetch_env.clipping`` lists every place and its rule).  Turn
    it into an error with ``warnings.simplefilter("error", ParameterClippedWarning)``.
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

    def __reduce__(self) -> tuple[Any, ...]:
        # pickled whole, notes too (a probe run's error comes back from a worker process)
        return (type(self), (self.args[0], self.scene, self.action), self.__dict__)

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


def require_pieces(name: str, pieces: Any) -> None:
    """Refuse anything but a non-empty tuple or list of :class:`fetch_env.layouts.Piece`."""
    from fetch_env.layouts import Piece  # (layouts imports this module)

    require(isinstance(pieces, tuple | list) and len(pieces) > 0, name, _Shown(pieces),
            "a non-empty sequence of Piece")
    for i, p in enumerate(pieces):
        require(isinstance(p, Piece), f"{name}[{i}]", _Shown(p), "a Piece")


def require_type(name: str, value: Any, kind: type | tuple[type, ...], what: str) -> None:
    """Refuse ``value`` unless it is a ``kind``: another object would fail later with a bare
    ``AttributeError`` or ``TypeError``."""
    require(isinstance(value, kind), name, _Shown(value), what)


def env_error_line(exc: BaseException) -> str:
    """The first line of an error raised while building an env, without the suffix
    gymnasium appends (" was raised from the environment creator for ... with kwargs ...")."""
    lines = str(exc).strip().splitlines()
    line = lines[0] if lines else type(exc).__name__
    return line.split(" was raised from the environment creator")[0]


def _short(value: Any, limit: int = 60) -> str:
    shown = repr(value)
    return shown if len(shown) <= limit else shown[:limit - 3] + "..."


def check_annotated(func: Callable[..., Any], values: Mapping[str, Any]) -> None:
    """Refuse each argument of ``func`` in ``values`` whose type is not its annotation's.

    Only the simple annotations are checked (``float``, ``int``, ``bool``, ``str``, each
    optionally ``| None``); others are left to the caller's own checks.  A ``float`` must be a
    finite real number (:func:`require_finite`), an ``int`` an integer, a ``bool`` ``True`` or
    ``False``, a ``str`` text.  Run first, so that the range checks that follow compare
    numbers with numbers instead of raising a bare ``TypeError`` (``"x" < 1``) or
    ``ValueError`` (an array's ambiguous truth) from inside.
    """
    for name, param in inspect.signature(func).parameters.items():
        if name not in values or name == "self":
            continue
        ann = param.annotation
        text = ann if isinstance(ann, str) else getattr(ann, "__name__", str(ann))
        parts = {p.strip().strip("'\"") for p in text.split("|")}
        optional = "None" in parts
        parts.discard("None")
        value = values[name]
        if len(parts) != 1 or (value is None and optional):
            continue
        kind = parts.pop()
        if kind == "float":
            require_finite(name, value)
        elif kind == "int":
            require_int(name, value)
        elif kind == "bool":
            require(isinstance(value, bool | np.bool_), name, _Shown(value), "True or False")
        elif kind == "str":
            require(isinstance(value, str), name, _Shown(value), "a str")


class _Shown:
    """A value's repr shortened for a one-line error message, made only when the message is
    (the repr of a piece's arrays costs ~4 % of a Block episode, and checks pass)."""

    def __init__(self, value: Any) -> None:
        self.value = value

    def __repr__(self) -> str:
        return _short(self.value)


def check_reset(seed: Any, options: Any) -> tuple[int | None, dict[str, Any]]:
    """An environment's ``reset`` arguments checked: the seed (None or an integer >= 0, as
    gymnasium takes it; a numpy integer is accepted as a Python one) and the options (None or
    a mapping; its ``preset`` a name, its ``pieces`` a list or tuple), returned as
    ``(seed, dict(options))``.  gymnasium would raise its own ``Error`` for a bad seed and
    ``dict()`` a bare ``TypeError``/``ValueError`` for options that are not a mapping."""
    if seed is not None:
        require_int("seed", seed)
        require(seed >= 0, "seed", seed, "None or an integer >= 0")
        seed = int(seed)
    require(options is None or isinstance(options, Mapping), "options", _Shown(options),
            "None or a dict of reset options")
    opts = dict(options or {})
    if "preset" in opts:
        require(isinstance(opts["preset"], str), "options['preset']", _Shown(opts["preset"]),
                "a scene preset name (str)")
    if "pieces" in opts:
        require(isinstance(opts["pieces"], tuple | list), "options['pieces']",
                _Shown(opts["pieces"]), "a non-empty list or tuple of Piece")
    return seed, opts
