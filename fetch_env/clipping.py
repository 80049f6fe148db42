"""Every place the simulator clips, caps or replaces a value, and how it says so.

Nothing is changed silently: where a value given to the simulator (or drawn by an
environment) is not used as it is, the change is

* reported in the results, as a record ``{"name", "given", "applied", "reason"}`` (JSON-able,
  no timings, so same-seed infos stay equal): an environment's ``info["clipped"]`` (a list,
  empty when nothing changed), the command line's ``clipped`` in its JSON and a line of its
  text output;
* warned about in the Python API as :class:`fetch_env.errors.ParameterClippedWarning`, with
  the caller's line as the warning's location.  An environment warns once per instance for
  each :data:`RULES` key (a training run steps millions of times; SB3 already clips its
  policy's actions to the space) and reports every occurrence in ``info["clipped"]``.

The rules (``RULES``: key -> where and what):

* ``young``: a piece's Young's modulus above the conditioning limit of MuJoCo's implicit
  step is simulated at the limit (:func:`fetch_env.scene.simulated_young`): ``1e4 rho s^2 /
  dt^2`` (rho the density, s the piece's thinnest extent, dt the physics step): 9e7 Pa for a
  15 mm, 1000 kg/m^3 cube at the 5 ms step.  A piece that stiff deforms < 1 % in any clamp.
* ``action``: an environment action outside ``[-1, 1]`` is clipped to it (the action space).
* ``theta_d``: an environment's clamp angle is capped at 0.98 of the angle at which the
  half-spoons' tips meet for the scene (``theta_closed``).
* ``end_stop``: the controller never closes past ``theta_closed - CLOSED_MARGIN`` (0.01 rad):
  a larger theta_d is run to that end stop (``SimResult.extra["theta_d_applied"]``).
* ``hold``: with ``lift_at_settling=True`` the settling time from the estimates is capped at
  ``max_hold``.
* ``observation``: an observation feature beyond ``+-OBS_BOUND`` (10) after scaling is
  clipped to it (layout features of scenes far outside the sampled ranges).

Not counted as changes of a user's value, and documented where they apply: a motor stall
(physics: the 2 N m motor stops, ``extra["stalled_at"]``), an estimated parameter the
observation cannot hold (reported as not identified: flag 0, ``estimated_params`` None), the
probes' clamp angle (chosen by the probe from ``probe_strain``, never given), the time-scaled
hold's longest stride (``MAX_TIME_SCALE`` steps, part of ``probe_time_growth``'s definition),
and the estimators' internal guards (fitted exponents kept in the float range, the error
model's standardized inputs kept within its fitted range): the estimators change no value
they are given.
"""

from __future__ import annotations

import contextvars
import math
import os
import sys
import warnings
import weakref
from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from typing import Any

from fetch_env.errors import ParameterClippedWarning

# The user's part: the rules and the switch for callers that report the changes themselves.
# record, message, warn and warn_once serve the package's own modules and command line.
__all__ = ["RULES", "ClipRecord", "reported_elsewhere"]

ClipRecord = dict[str, Any]  # {"name", "given", "applied", "reason"}

RULES: dict[str, str] = {
    "young": "Young's modulus above MuJoCo's conditioning limit (1e4 rho s^2 / dt^2) is "
             "simulated at the limit",
    "action": "actions outside [-1, 1] are clipped to the action space",
    "theta_d": "theta_d is capped at 0.98 theta_closed (the blades' tips meet there)",
    "end_stop": "the controller's end stop: the blades stop 0.01 rad before their tips meet",
    "hold": "the settling hold is capped at max_hold",
    "observation": "observation features are clipped to +-OBS_BOUND after scaling",
}

# Set while a caller reports the changes itself (an env's info, the CLI's text): the
# simulator's own warnings are then not raised a second time.
_QUIET: contextvars.ContextVar[bool] = contextvars.ContextVar("clip_quiet", default=False)
_WARNED: weakref.WeakKeyDictionary[Any, set[str]] = weakref.WeakKeyDictionary()
_PACKAGE = os.path.dirname(os.path.abspath(__file__)) + os.sep


def record(rule: str, name: str, given: float, applied: float, reason: str) -> ClipRecord:
    """One change: ``name`` was ``given`` and ``applied`` was used, because ``reason``.

    ``rule`` is a :data:`RULES` key (kept in the record, so a reader can group them).
    """
    return {"rule": rule, "name": name, "given": float(given), "applied": float(applied),
            "reason": reason}


def message(rec: ClipRecord) -> str:
    """One line for a record: ``name given -> applied (reason)``."""
    return f"{rec['name']} {rec['given']:.6g} -> {rec['applied']:.6g} ({rec['reason']})"


@contextmanager
def reported_elsewhere() -> Iterator[None]:
    """Within this block the simulator raises no :class:`ParameterClippedWarning`: the
    caller reports the changes itself (in ``info``, or as text)."""
    token = _QUIET.set(True)
    try:
        yield
    finally:
        _QUIET.reset(token)


def _stacklevel() -> int:
    """The stack level of the first frame outside this package and gymnasium's wrappers:
    the user's line that asked for the value, as the warning's location."""
    frame = sys._getframe(1)
    level = 1
    while frame is not None and (frame.f_code.co_filename.startswith(_PACKAGE)
                                 or f"{os.sep}gymnasium{os.sep}" in frame.f_code.co_filename):
        frame = frame.f_back
        level += 1
    return level


def warn(records: Iterable[ClipRecord], suffix: str = "") -> None:
    """Warn about each record (unless :func:`reported_elsewhere` is active)."""
    for rec in records:
        rewarn(ParameterClippedWarning, message(rec) + suffix)


def rewarn(category: type[Warning], text: str) -> None:
    """Warn ``text`` again, as this package warns (the user's line as its location): a
    warning a worker process caught (:mod:`fetch_env.parallel`); a clipping one only where
    :func:`reported_elsewhere` is not active here."""
    if issubclass(category, ParameterClippedWarning) and _QUIET.get():
        return
    warnings.warn(text, category, stacklevel=_stacklevel())


def warn_once(owner: Any, records: Iterable[ClipRecord], where: str) -> None:
    """Warn about the first record of each rule that ``owner`` (an env) has not warned about
    yet; later ones are only in ``where`` (e.g. ``info["clipped"]``)."""
    try:
        seen = _WARNED.setdefault(owner, set())
    except TypeError:  # not weak-referenceable: warn every time rather than never
        seen = set()
    first = []
    for rec in records:
        if rec["rule"] not in seen:
            seen.add(rec["rule"])
            first.append(rec)
    warn(first, f"; this env warns once per kind, every occurrence is in {where}")


def reset_clips(env: Any, pieces: tuple[Any, ...], info: dict[str, Any]) -> list[ClipRecord]:
    """What an environment's reset changed: the moduli its fetch scene and (with
    ``estimator="model"``) its probes simulate capped, the settling hold capped at
    ``max_hold``, and observation features clipped.  ``env`` is a ``FoodFetchEnv`` after
    ``_observe``; ``info`` its reset info."""
    from fetch_env.env_scenes import layout_features
    from fetch_env.scene import BASE_TIMESTEP, young_caps
    from fetch_env.spaces import feature_clips

    out = young_caps(pieces, env.fetch_timestep)
    if env.estimator == "model":
        k, config = int(info["probe_piece"]), env.probe_config
        for probe, step in (("relaxation", config.relaxation_timestep or BASE_TIMESTEP),
                            ("slip", config.slip_timestep)):
            out += young_caps((pieces[k],), step, first=k, where=f" in the {probe} probe")
    out += _settling_cap(env, info)
    out += feature_clips(layout_features(pieces))
    return out


def _settling_cap(env: Any, info: dict[str, Any]) -> list[ClipRecord]:
    """The record of the settling hold capped at ``max_hold`` (``lift_at_settling=True``):
    the settling time ``tau1 ln(g1 / ((1 - g1) tol))`` of ``FoodFetchEnv._hold_from``."""
    est = info.get("estimated_params") or {}
    g1, tau1 = est.get("g1"), est.get("tau1")
    if not env.lift_at_settling or g1 is None or tau1 is None or not (0 < g1 < 1 and tau1 > 0):
        return []
    t_s = tau1 * math.log(max(g1 / ((1 - g1) * env.settling_tolerance), 1.0))
    if t_s <= env.max_hold:
        return []
    return [record("hold", "hold (settling time t_s)", t_s, env.max_hold,
                   "capped at max_hold")]
