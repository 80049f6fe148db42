"""Errors and input validation shared by the estimators.

Every estimator either returns a number it can stand behind, flags it ``reliable=False`` with a
warning that says why, or raises :class:`EstimationError` with a message naming the bad value.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["EstimationError", "as_trace", "check_traces", "floats", "instance", "mapping",
           "optional_real", "real"]


class EstimationError(ValueError):
    """Raised when a trace cannot give an estimate (bad input or missing phase)."""


def real(name: str, value: object) -> float:
    """``value`` as a float, if it is a real number (int or float, numpy's too; not a bool,
    text, complex, None or an array); else :class:`EstimationError` naming ``name``.
    Finiteness and ranges are the caller's to check."""
    if isinstance(value, bool | np.bool_) or not isinstance(
            value, int | float | np.integer | np.floating):
        shown = repr(value)
        shown = shown if len(shown) <= 60 else shown[:57] + "..."
        raise EstimationError(f"{name} must be a real number, got {shown}")
    return float(value)


def _shown(value: object, limit: int = 60) -> str:
    shown = repr(value)
    return shown if len(shown) <= limit else shown[:limit - 3] + "..."


def instance(name: str, value: object, kind: type | tuple[type, ...], what: str) -> None:
    """Refuse ``value`` unless it is a ``kind`` (e.g. a ``ClampGeometry``), naming it: an
    object of another type would fail later with a bare ``AttributeError``."""
    if not isinstance(value, kind):
        raise EstimationError(f"{name} must be {what}, got {_shown(value)}")


def mapping(name: str, value: object) -> Mapping[str, object]:
    """``value`` if it is a mapping (e.g. ``{"K1": ..., "g1": ...}``), else the error."""
    instance(name, value, Mapping, "a mapping of name -> value")
    return value  # type: ignore[return-value]


def floats(name: str, values: ArrayLike) -> NDArray[np.float64]:
    """``values`` (a number or an array of any shape) as float64, if they are real numbers
    (not text, complex, None or objects); NaN and infinities pass (the caller decides)."""
    try:
        raw = np.asarray(values)
        ok = raw.dtype.kind in "biufO"
        arr = raw.astype(np.float64) if ok else raw
    except (TypeError, ValueError):
        ok = False
    if not ok:
        raise EstimationError(f"{name} must be real numbers, got {_shown(values)}")
    return arr


def optional_real(name: str, value: object) -> float | None:
    """:func:`real`, passing None through (an option left to be inferred)."""
    return None if value is None else real(name, value)


def as_trace(name: str, values: ArrayLike) -> NDArray[np.float64]:
    """Return ``values`` as a 1-D float64 array, raising if it is not finite.

    Args:
        name: name of the trace, used in error messages (e.g. ``"M"``).
        values: the samples.

    Raises:
        EstimationError: if the trace is not numbers (strings, objects, complex: numpy would
            raise a bare ``ValueError``/``TypeError`` or drop the imaginary part with only a
            warning), is not 1-D or holds NaN/inf samples.
    """
    try:
        raw = np.asarray(values)
        # numbers, or objects that are numbers (e.g. a list mixing ints and floats); never
        # text, which numpy would parse, nor complex
        ok = raw.dtype.kind in "biufO"
        arr = raw.astype(np.float64) if ok else raw
    except (TypeError, ValueError):  # ragged nested sequences
        ok = False
    if not ok:
        shown = repr(values)
        shown = shown if len(shown) <= 80 else shown[:77] + "..."
        raise EstimationError(f"trace {name!r} must be real numbers, got {shown}")
    if arr.ndim != 1:
        raise EstimationError(f"trace {name!r} must be 1-D, got shape {arr.shape}")
    bad = ~np.isfinite(arr)
    if bad.any():
        idx = int(np.flatnonzero(bad)[0])
        raise EstimationError(
            f"trace {name!r} has {int(bad.sum())} non-finite (NaN/inf) sample(s), "
            f"first at index {idx} (value {arr[idx]})"
        )
    return arr


MIN_SAMPLE_INTERVAL = 1e-6  # [s] no force or angle sensor samples faster than a megahertz
MAX_SAMPLE = 1e12  # a sample beyond this, in SI units, is a unit slip or a corrupt log


def check_traces(
    t: ArrayLike, min_samples: int = 10, **traces: ArrayLike
) -> tuple[NDArray[np.float64], dict[str, NDArray[np.float64]]]:
    """Validate a time vector and traces sampled on it.

    Args:
        t: sample times in seconds; must be strictly increasing.
        min_samples: fewest samples accepted.
        **traces: named traces, each the same length as ``t``.

    Returns:
        ``(t, traces)`` as float64 arrays.

    Raises:
        EstimationError: too few samples, mismatched lengths, NaN/inf samples, time that is
            unsorted, repeated or sampled faster than ``MIN_SAMPLE_INTERVAL``, or a sample
            beyond ``MAX_SAMPLE``.
    """
    tt = as_trace("t", t)
    out = {name: as_trace(name, v) for name, v in traces.items()}
    for name, v in out.items():
        if v.size != tt.size:
            raise EstimationError(
                f"mismatched lengths: trace {name!r} has {v.size} samples but t has {tt.size}"
            )
    if tt.size < min_samples:
        raise EstimationError(
            f"trace too short: {tt.size} samples, at least {min_samples} are needed"
        )
    dt = np.diff(tt)
    if np.any(dt <= 0.0):
        idx = int(np.flatnonzero(dt <= 0.0)[0])
        kind = "repeated" if dt[idx] == 0.0 else "unsorted (decreasing)"
        raise EstimationError(
            f"time t is {kind} at index {idx + 1}: t[{idx}]={tt[idx]!r}, "
            f"t[{idx + 1}]={tt[idx + 1]!r}; t must be strictly increasing"
        )
    if dt.size and dt.min() < MIN_SAMPLE_INTERVAL * (1.0 - 1e-6):  # (1 MHz's own rounding)
        idx = int(np.argmin(dt))
        raise EstimationError(
            f"time t steps by {dt[idx]:.3g} s at index {idx + 1}, below "
            f"{MIN_SAMPLE_INTERVAL:g} s (a megahertz): t must be in seconds"
        )
    for name, v in {"t": tt, **out}.items():
        if np.max(np.abs(v)) > MAX_SAMPLE:
            idx = int(np.argmax(np.abs(v)))
            raise EstimationError(f"{name}[{idx}]={v[idx]!r} is beyond +-{MAX_SAMPLE:g} (SI "
                                  "units: s, rad, N, N m)")
    return tt, out
