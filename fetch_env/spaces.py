"""The environments' action and observation spaces: names, scaling, encode and decode.

Actions are ``Box(-1, 1, (3,))`` mapped linearly onto physical ranges; observations are
estimated food properties and camera features, each mapped to order one either linearly
(``value / scale``) or logarithmically (``log10(value / scale)``, for the spring and dashpot
constants, which span five decades between the softest and the hardest food).
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Iterator, Mapping
from typing import Any

import numpy as np

from fetch_env import clipping
from fetch_env.clipping import ClipRecord
from fetch_env.errors import InvalidParameterError, require, require_finite


def _short(value: Any, limit: int = 80) -> str:
    """``repr(value)``, cut to ``limit`` characters for a one-line message."""
    shown = repr(value)
    return shown if len(shown) <= limit else shown[:limit - 3] + "..."

# --------------------------------------------------------------------------------------------
# actions

ACTION_NAMES: tuple[str, ...] = ("theta_d", "omega", "lift_speed")
ACTION_RANGES: dict[str, tuple[float, float]] = {
    "theta_d": (0.02, 0.12),  # [rad] clamp angle from the open pose; study: 0.0244 to 0.09
    "omega": (0.01, 0.4),  # [rad/s] clamping angular velocity; study: 0.01 to 0.4
    "lift_speed": (0.004, 0.04),  # [m/s] lifting speed; study: 4 to 40 mm/s
}
_ACT_LO = np.array([ACTION_RANGES[k][0] for k in ACTION_NAMES])
_ACT_HI = np.array([ACTION_RANGES[k][1] for k in ACTION_NAMES])


def _as_floats(name: str, value: Any, expectation: str) -> np.ndarray:
    """``value`` as a float64 array, or the package's error naming it.

    numpy raises a bare ``ValueError``/``TypeError`` for strings and odd objects and drops a
    complex number's imaginary part with only a warning; both are refused here instead.
    """
    try:
        raw = np.asarray(value)
        # numbers, or objects that are numbers (e.g. a list mixing ints and floats); never
        # text, which numpy would parse, nor complex
        ok = raw.dtype.kind in "biufO"
        arr = raw.astype(np.float64) if ok else raw
    except (TypeError, ValueError):
        ok = False
    if not ok:
        raise InvalidParameterError(f"{name} must be {expectation}, got {_short(value)}")
    return arr


def clip_action(action: Any) -> tuple[np.ndarray, list[ClipRecord]]:
    """The action as a float64 (3,) array clipped to [-1, 1], and a
    :mod:`fetch_env.clipping` record per component that was outside (as SB3 clips its
    policies' actions); raises naming the value if it is NaN/inf, not numbers or misshaped."""
    a = _as_floats("action", action,
                   "3 numbers in [-1, 1] (theta_d, omega, lift_speed)")
    if a.shape != (3,):
        raise InvalidParameterError(
            f"action must have shape (3,) (theta_d, omega, lift_speed), got shape {a.shape}: "
            f"{_short(action)}")
    if not np.isfinite(a).all():
        raise InvalidParameterError(f"action must be finite, got {_short(action)}")
    clipped = np.clip(a, -1.0, 1.0)
    records = [clipping.record("action", f"action[{i}] ({ACTION_NAMES[i]})", a[i], clipped[i],
                               "outside the action space [-1, 1]")
               for i in np.flatnonzero(clipped != a)]
    return clipped, records


def check_action(action: Any) -> np.ndarray:
    """The action as a float64 (3,) array; raises naming the value if NaN/inf or misshaped.

    Finite values outside [-1, 1] are clipped (as SB3 does for its policies), with a
    :class:`~fetch_env.errors.ParameterClippedWarning` (:func:`clip_action` returns the
    changes instead).
    """
    a, records = clip_action(action)
    clipping.warn(records)
    return a


def theta_d_cap(theta_d: float, theta_closed: float) -> tuple[float, list[ClipRecord]]:
    """An environment's clamp angle, capped at 0.98 of ``theta_closed`` (the angle at which
    the half-spoons' tips meet for the scene), and the record of the cap where it applied."""
    require_finite("theta_d", theta_d)
    require(isinstance(theta_closed, numbers.Real) and theta_closed > 0, "theta_closed",
            theta_closed, "a number > 0 rad (inf: no cap)")
    applied = min(theta_d, 0.98 * theta_closed)
    if applied >= theta_d:
        return theta_d, []
    return applied, [clipping.record(
        "theta_d", "theta_d", theta_d, applied,
        f"capped at 0.98 theta_closed: the tips of the half-spoons meet at {theta_closed:.4f} "
        "rad for this scene")]


def end_stop_records(theta_d: float, extra: Mapping[str, Any],
                     theta_closed: float) -> list[ClipRecord]:
    """The record of the controller's end stop where it stopped the clamp short of
    ``theta_d`` (``extra``: a run's ``SimResult.extra``; a stall is physics, not a cap)."""
    if not isinstance(extra, Mapping):
        raise InvalidParameterError(f"extra must be a run's SimResult.extra, got {_short(extra)}")
    require_finite("theta_d", theta_d)
    applied = extra.get("theta_d_applied")
    if applied is None or extra.get("stalled_at") is not None or not applied < theta_d:
        return []
    return [clipping.record(
        "end_stop", "theta_d", theta_d, applied,
        f"the controller's end stop, {theta_closed - applied:.3g} rad before the half-spoons' "
        f"tips meet at {theta_closed:.4f} rad")]


def action_to_physical(action: Any) -> dict[str, float]:
    """Map an action in [-1, 1]^3 linearly onto ``ACTION_RANGES`` (SI units); values outside
    [-1, 1] are clipped with a :class:`~fetch_env.errors.ParameterClippedWarning`."""
    a = check_action(action)
    # (clipped: at a = 1 the rounding of the affine map can land an ulp above the range)
    phys = np.clip(_ACT_LO + (a + 1.0) / 2.0 * (_ACT_HI - _ACT_LO), _ACT_LO, _ACT_HI)
    return {k: float(v) for k, v in zip(ACTION_NAMES, phys, strict=True)}


def physical_to_action(theta_d: float, omega: float, lift_speed: float) -> np.ndarray:
    """The action (float32, (3,)) that maps to these physical values; raises if out of range."""
    given = (theta_d, omega, lift_speed)
    for name, v, lo, hi in zip(ACTION_NAMES, given, _ACT_LO, _ACT_HI, strict=True):
        x = _as_floats(name, v, f"a number in [{lo}, {hi}]")
        if not (x.shape == () and np.isfinite(x) and lo - 1e-12 <= x <= hi + 1e-12):
            raise InvalidParameterError(f"{name} must be in [{lo}, {hi}], got {v!r}")
    phys = np.array([float(v) for v in given], dtype=np.float64)
    return np.clip(2.0 * (phys - _ACT_LO) / (_ACT_HI - _ACT_LO) - 1.0, -1, 1).astype(np.float32)


# --------------------------------------------------------------------------------------------
# observations

# name -> (transform, scale, unit).  Parameter features come first; each group of estimated
# parameters has a validity flag (1: a number the estimator stands behind or the oracle's,
# 0: not available, the feature is then 0).
OBS_SPEC: dict[str, tuple[str, float, str]] = {
    "K1": ("log10", 1e3, "N/m"),
    "K2": ("log10", 1e3, "N/m"),
    "B": ("log10", 1e4, "N s/m"),
    "mu": ("linear", 1.0, "-"),
    "g1": ("linear", 1.0, "-"),
    "tau1": ("linear", 5.0, "s"),
    "visco_valid": ("linear", 1.0, "flag"),
    "friction_valid": ("linear", 1.0, "flag"),
    "n_pieces": ("linear", 10.0, "count"),
    "mean_size": ("linear", 0.015, "m"),
    "max_height": ("linear", 0.015, "m"),
    "min_spacing_across": ("linear", 0.001, "m"),
    "min_spacing_along": ("linear", 0.001, "m"),
    "span_along": ("linear", 0.03, "m"),
    "total_mass": ("linear", 0.005, "kg"),
}
OBS_NAMES: tuple[str, ...] = tuple(OBS_SPEC)
OBS_SCALE: dict[str, float] = {k: v[1] for k, v in OBS_SPEC.items()}
OBS_TRANSFORM: dict[str, str] = {k: v[0] for k, v in OBS_SPEC.items()}
OBS_UNITS: dict[str, str] = {k: v[2] for k, v in OBS_SPEC.items()}
VISCO_NAMES: tuple[str, ...] = ("K1", "K2", "B", "g1", "tau1")
FRICTION_NAMES: tuple[str, ...] = ("mu",)
OBS_BOUND = 10.0  # every feature is clipped to [-OBS_BOUND, OBS_BOUND]


def _encode_one(name: str, value: float) -> float:
    transform, scale, _ = OBS_SPEC[name]
    if transform == "log10":
        q = value / scale
        # the quotient of a tiny positive value underflows to 0, which log10 refuses
        return math.log10(q) if q > 0 else math.log10(value) - math.log10(scale)
    return value / scale


def _value(values: Mapping[str, float], name: str, default: float | None = None) -> float:
    """``values[name]`` as a float (NaN allowed), or the package's error naming what is wrong:
    a missing feature or one that is not a real number (a bare ``KeyError``/``ValueError``)."""
    if name not in values and default is not None:
        return default
    if name not in values:
        raise InvalidParameterError(f"observation value {name!r} is missing")
    if values[name] is None:  # (numpy would read it as NaN)
        raise InvalidParameterError(f"{name} must be a real number, got None")
    x = _as_floats(name, values[name], "a real number")
    if x.shape != ():
        raise InvalidParameterError(
            f"{name} must be a real number, got {_short(values[name])}")
    return float(x)


def feature_clips(values: Mapping[str, float]) -> list[ClipRecord]:
    """A :mod:`fetch_env.clipping` record for each layout feature in ``values`` (SI) that the
    observation clips to ``+-OBS_BOUND`` after scaling (estimated parameters out of bounds
    are not clipped but reported as not identified)."""
    if not isinstance(values, Mapping):
        raise InvalidParameterError(
            f"observation values must be a mapping of name -> SI value, got {_short(values)}")
    out = []
    for n in OBS_NAMES:
        if n in VISCO_NAMES or n in FRICTION_NAMES or n not in values:
            continue
        v = _value(values, n)
        e = _encode_one(n, v) if math.isfinite(v) else math.nan
        if math.isfinite(e) and abs(e) > OBS_BOUND:
            kept = math.copysign(OBS_BOUND, e)
            si = 10.0 ** kept * OBS_SCALE[n] if OBS_TRANSFORM[n] == "log10" else kept * OBS_SCALE[n]
            out.append(clipping.record(
                "observation", f"observation {n}", v, si,
                f"{OBS_TRANSFORM[n]} feature {e:.3g} clipped to +-{OBS_BOUND:g}"))
    return out


def encode_observation(values: Mapping[str, float]) -> np.ndarray:
    """SI values -> the float32 observation.  Estimated parameters that are NaN, not positive
    (log features) or outside the bounds after scaling are reported as 0 with their group's
    flag cleared, so a wild estimate never reaches the policy as a huge number.  Other
    features beyond the bounds are clipped to them, with a
    :class:`~fetch_env.errors.ParameterClippedWarning` (:func:`feature_clips` lists them)."""
    if not isinstance(values, Mapping):
        raise InvalidParameterError(
            f"observation values must be a mapping of name -> SI value, got {_short(values)}")
    obs = np.zeros(len(OBS_NAMES), dtype=np.float64)
    flags = {"visco_valid": _value(values, "visco_valid", 0.0),
             "friction_valid": _value(values, "friction_valid", 0.0)}
    for name, flag in flags.items():
        if not math.isfinite(flag):  # a NaN flag would reach the policy as NaN
            raise InvalidParameterError(f"{name} must be a finite number, got {flag!r}")
    for group, names in (("visco_valid", VISCO_NAMES), ("friction_valid", FRICTION_NAMES)):
        if not flags[group]:
            continue
        enc = {}
        for n in names:
            v = _value(values, n)
            ok = math.isfinite(v) and (v > 0 or OBS_TRANSFORM[n] == "linear")
            e = _encode_one(n, v) if ok else math.nan
            if not (math.isfinite(e) and abs(e) <= OBS_BOUND):
                flags[group] = 0.0
                break
            enc[n] = e
        else:
            for n, e in enc.items():
                obs[OBS_NAMES.index(n)] = e
    for i, n in enumerate(OBS_NAMES):
        if n in flags:
            obs[i] = flags[n]
        elif n not in VISCO_NAMES and n not in FRICTION_NAMES:
            v = _value(values, n)
            if not math.isfinite(v):  # layout features are measured, never missing
                raise InvalidParameterError(f"{n} must be a finite number, got {v!r}")
            obs[i] = _encode_one(n, v)
    if np.abs(obs).max() > OBS_BOUND:
        clipping.warn(feature_clips(values))
    return np.clip(obs, -OBS_BOUND, OBS_BOUND).astype(np.float32)


def decode_observation(obs: Any) -> dict[str, float]:
    """The observation back in SI units (see ``OBS_UNITS``); estimated parameters whose
    validity flag is 0 decode to NaN, and counts to whole numbers (float32 leaves one
    piece as 1.0000000149, which a rule testing ``== 1`` would miss)."""
    o = _as_floats("observation", obs, f"{len(OBS_NAMES)} finite numbers")
    if o.shape != (len(OBS_NAMES),):
        raise InvalidParameterError(
            f"observation must have shape ({len(OBS_NAMES)},), got {o.shape}")
    if not np.isfinite(o).all():
        raise InvalidParameterError(f"observation must be finite, got {_short(obs)}")
    out: dict[str, float] = {}
    for i, n in enumerate(OBS_NAMES):
        transform, scale, unit = OBS_SPEC[n]
        out[n] = float(10.0 ** o[i] * scale if transform == "log10" else o[i] * scale)
        if unit == "count":
            out[n] = float(round(out[n]))
    for group, names in (("visco_valid", VISCO_NAMES), ("friction_valid", FRICTION_NAMES)):
        if out[group] < 0.5:
            for n in names:
                out[n] = math.nan
    return out


class Traces(Mapping[str, np.ndarray]):
    """Read-only mapping of trace name -> array, as ``info["traces"]``.

    Not a ``dict`` on purpose: Gymnasium's vector envs stack dict-valued infos key by key and
    fail on arrays whose length differs between sub-environments (the traces' length depends
    on the action); any other object is kept whole per sub-environment.
    """

    def __init__(self, traces: Mapping[str, np.ndarray]) -> None:
        if not isinstance(traces, Mapping):
            raise InvalidParameterError(
                f"traces must be a mapping of name -> array, got {_short(traces)}")
        self._data = {k: np.asarray(v) for k, v in traces.items()}

    def __getitem__(self, key: str) -> np.ndarray:
        return self._data[key]

    def __iter__(self) -> Iterator[str]:
        return iter(self._data)

    def __len__(self) -> int:
        return len(self._data)

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Traces):
            return NotImplemented
        return self._data.keys() == other._data.keys() and all(
            a.shape == other._data[k].shape and np.array_equal(a, other._data[k])
            for k, a in self._data.items())

    def __hash__(self) -> int:  # mutable contents by reference: identity hash
        return id(self)

    def __repr__(self) -> str:
        n = len(next(iter(self._data.values()))) if self._data else 0
        return f"Traces({', '.join(self._data)}; {n} samples)"
