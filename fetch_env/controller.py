"""The fetch as phases, and the study's two probe experiments, with their sensor traces.

Every experiment starts with the pieces settling on the plate under gravity with the
half-spoons at the open pose, then follows a prescribed profile of the hinge angle theta(t)
(the study's angle: 0 at the open pose, growing as the blades close) and the stage height:

* ``fetch``: clamp at constant omega to theta_d, hold, lift at constant speed by
  ``lift_height``, hold in the air (rolled by ``tilt`` toward the mouth where it is set:
  :mod:`fetch_env.carry`).
* ``relaxation``: clamp at omega to theta_d, hold (long) while the moment relaxes.
* ``slip``: clamp to theta_d, hold briefly, then move the closed pair ``slide_distance``
  toward the plate over ``slide_time`` so the plate holds the food and the blades slide.
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, Literal

import mujoco
import numpy as np

from fetch_env.carry import TILT_RAMP, TiltLoad, tilt_angles
from fetch_env.errors import InvalidParameterError, SimulationDivergedError, require, require_finite
from fetch_env.layouts import Piece
from fetch_env.metrics import residual_plastic_strain
from fetch_env.recording import TraceRecorder
from fetch_env.scene import (
    BLADE_HALF_THICKNESS,
    MIN_CONTACT_TIMECONST,
    MIN_PIECE_CONTACT_TIMECONST,
    STIFF_CONTACT_CUBE_MESH,
    Geometry,
    Scene,
    build_scene,
    initial_state,
    simulated_young,
)
from fetch_env.viscoelastic import PronyRelaxation
from fetch_env.warmstart import AlternatingWarmstart, Warmstart, check_warmstart

Experiment = Literal["fetch", "relaxation", "slip"]
EXPERIMENTS: tuple[str, ...] = ("fetch", "relaxation", "slip")
PHASES: tuple[str, ...] = ("settle", "clamp", "hold", "lift", "air", "slide")
PHASE_CODE = {name: i for i, name in enumerate(PHASES)}
SERVO_TIME_CONSTANT = 0.005  # [s] kv / kp of the hinge and lift servos (fetch_base.xml)
THETA_D_RANGE = (0.0, 0.3)  # [rad]
OMEGA_RANGE = (1e-3, 2.0)  # [rad/s]
LIFT_SPEED_RANGE = (1e-4, 0.1)  # [m/s]
STALL_MOMENT = 2.0  # [N m] the clamping motor stalls above this load (~50 N at L = 38 mm)
CLOSED_MARGIN = 0.01  # [rad] the end stop, before the faces meet at the tips
STALL_TIME = 0.02  # [s] the load is averaged over this long before the motor stalls
MAX_TIME_SCALE = 50.0  # [-] most physical steps one step of a time-scaled hold stands for
RELAXATION_GAP = 1e-4  # [m] blade-food clearance at the start of the relaxation probe
# Relaxation experiment: least contact stiffness 1 / tc^2 per unit of the food's E / (rho s^2)
# (see relaxation_contact_timeconst).  0.0075 keeps the default 10 ms contact up to ~0.3 MPa
# at 15 mm; 0.0225 and 0.05 were also measured (seeds 5000-5127): 0.05 misfitted K on some
# scenes, and 0.0225 was no better than 0.0075.
RELAXATION_CONTACT_RATIO = 0.0075


@dataclass(frozen=True)
class FetchAction:
    """What the robot is told to do (SI units).

    Attributes:
        theta_d: preset angular displacement the clamp stops at [rad], from the open pose.
        omega: clamping angular velocity [rad/s].
        lift_speed: lifting speed [m/s].
        hold: time held at theta_d before lifting (fetch) or before sliding (slip);
            the relaxation time for the relaxation probe [s].
        lift_height: lift distance [m].
        air_hold: time held in the air after the lift [s].
        settle: time the pieces settle on the plate before the clamp [s].
        slide_distance: induced-slip travel toward the plate [m].
        slide_time: duration of the induced slip [s].
        tilt: roll of the closed pair about the clamp direction in the air hold (fetch),
            which tips the bite along the hinge axis where only friction holds it [rad]
            (:mod:`fetch_env.carry`); 0: none.
        tilt_ramp: time the roll takes, from the start of the air hold [s].
    """

    theta_d: float = 0.045
    omega: float = 0.1
    lift_speed: float = 0.005
    hold: float = 1.0
    lift_height: float = 0.005
    air_hold: float = 1.0
    settle: float = 0.3
    slide_distance: float = 0.005
    slide_time: float = 10.0
    tilt: float = 0.0
    tilt_ramp: float = TILT_RAMP

    def __post_init__(self) -> None:
        for f in dataclasses.fields(self):
            require_finite(f.name, getattr(self, f.name))
        require(THETA_D_RANGE[0] < self.theta_d <= THETA_D_RANGE[1], "theta_d", self.theta_d,
                f"in ({THETA_D_RANGE[0]}, {THETA_D_RANGE[1]}] rad")
        require(OMEGA_RANGE[0] <= self.omega <= OMEGA_RANGE[1], "omega", self.omega,
                f"in [{OMEGA_RANGE[0]}, {OMEGA_RANGE[1]}] rad/s")
        require(LIFT_SPEED_RANGE[0] <= self.lift_speed <= LIFT_SPEED_RANGE[1], "lift_speed",
                self.lift_speed, f"in [{LIFT_SPEED_RANGE[0]}, {LIFT_SPEED_RANGE[1]}] m/s")
        require(0 <= self.hold <= 600, "hold", self.hold, "in [0, 600] s")
        require(0 < self.lift_height <= 0.05, "lift_height", self.lift_height, "in (0, 0.05] m")
        require(0 <= self.air_hold <= 60, "air_hold", self.air_hold, "in [0, 60] s")
        require(0.05 <= self.settle <= 5, "settle", self.settle, "in [0.05, 5] s")
        require(0 < self.slide_distance <= 0.02, "slide_distance", self.slide_distance,
                "in (0, 0.02] m")
        require(0 < self.slide_time <= 120, "slide_time", self.slide_time, "in (0, 120] s")
        require(0 <= self.tilt <= 0.5 * math.pi, "tilt", self.tilt, "in [0, pi/2] rad")
        require(0 < self.tilt_ramp <= 10, "tilt_ramp", self.tilt_ramp, "in (0, 10] s")

    def to_dict(self) -> dict[str, float]:
        out = dataclasses.asdict(self)
        if not self.tilt:  # a fetch without the roll is written as before the roll existed
            del out["tilt"], out["tilt_ramp"]
        return out


@dataclass(frozen=True)
class TimeScale:
    """Quasi-static time scaling of a hold: the relaxation probe's (the env's probes use it)
    and, opt-in (the env's ``fetch_hold_scale``), the fetch's holds on the plate and in the air.

    Past the hold's first ``realtime`` seconds the blades stand still and only the food
    relaxes, slowly (tau_1 of seconds) against the mechanics (the contact's and the servo's
    ~5-20 ms).  There each physics step stands for ``factor`` steps of the material's time:
    the Prony terms advance ``factor * dt`` a step (:meth:`fetch_env.viscoelastic.
    PronyRelaxation.set_time_scale`) and the trace's time is stretched back to physical time,
    so the mechanics still settles within a few steps of every change while the relaxation
    runs ``factor`` times faster: the finite-element practice of time (mass) scaling a
    quasi-static step.  ``tests/test_probes.py`` holds the scaled hold to the real-time one
    (moments at the same physical times measured within 1.8 % on the study's soft foods,
    the relaxed fraction within 0.5 %) and to the SLS law.  The contacts are left as they
    are: scaling their damping down with the rest made them chatter (moment noise of +-5 %,
    measured).
    The first ``realtime`` seconds stay physical because a piece is still settling into the
    clamp then (it rocks for up to ~0.25 s, see ``probes.HOLD_SETTLE``; the fetch's holds
    keep 0.1 s, ``FETCH_HOLD_REALTIME``, which ``tests/test_quasi_static_fetch.py``
    and docs/validation/quasi-static-holds.md hold to the real-time fetch).

    ``clamp_speed`` > 0 (a fetch's or a relaxation's clamp) runs a clamp slower than
    ``clamp_speed`` rad/s as if it were that fast, each step standing for ``clamp_speed /
    omega`` steps of the material's time (at most ``MAX_TIME_SCALE``): a slow clamp is as
    quasi-static as a hold (the blades' tips move at millimetres a second, against the
    contact's and servo's ~5-20 ms), so only the relaxation needs its physical time, and the
    blades move per step as in a real clamp at ``clamp_speed``.  ``tests/
    test_quasi_static_fetch.py`` holds the scaled clamp to the real-time one, and
    docs/validation/quasi-static-holds.md the fetch's outcomes to the chaos floor.

    ``growth`` > 0 spaces the scaled steps logarithmically, as a relaxation test records its
    samples: each step stands for at least ``growth`` times the physical time elapsed since
    the hold began (and at most ``MAX_TIME_SCALE`` steps), so a hold of any length costs
    ``~ln(hold / realtime) / growth`` steps and the late hold, where the moment hardly moves,
    is crossed in long strides.

    Attributes:
        factor: physical seconds per simulated second in the scaled hold [-], 1 to 50 (the
            least, with ``growth``).
        realtime: start of the hold simulated unscaled [s].
        growth: least physical time a scaled step stands for, as a share of the hold's
            elapsed physical time [-], 0 (a constant ``factor``) to 0.5.
        clamp_speed: clamp speed a slower clamp is simulated at [rad/s], 0 (every clamp in
            real time) or within the action's clamp speeds.
    """

    factor: float = 1.0
    realtime: float = 0.25
    growth: float = 0.0
    clamp_speed: float = 0.0

    def __post_init__(self) -> None:
        require_finite("factor", self.factor)
        require_finite("realtime", self.realtime)
        require_finite("growth", self.growth)
        require(1.0 <= self.factor <= MAX_TIME_SCALE, "factor", self.factor,
                f"in [1, {MAX_TIME_SCALE:g}]")
        require(self.realtime >= 0.0, "realtime", self.realtime, ">= 0 s")
        require(0.0 <= self.growth <= 0.5, "growth", self.growth, "in [0, 0.5]")
        require_finite("clamp_speed", self.clamp_speed)
        require(self.clamp_speed == 0.0
                or OMEGA_RANGE[0] <= self.clamp_speed <= OMEGA_RANGE[1], "clamp_speed",
                self.clamp_speed, f"0 or in [{OMEGA_RANGE[0]}, {OMEGA_RANGE[1]}] rad/s")

    @property
    def holds_scaled(self) -> bool:
        """Whether a hold's steps are scaled (else the holds run in real time)."""
        return self.factor != 1.0 or self.growth > 0.0

    @property
    def scaled(self) -> bool:
        """Whether any step is scaled: a hold's or a slow clamp's."""
        return self.holds_scaled or self.clamp_speed > 0.0

    def step_times(self, elapsed: float, length: float, dt: float) -> np.ndarray:
        """The physical time each scaled step stands for [s], over ``length`` s of hold that
        starts ``elapsed`` s after the hold began (the last step is cut to end on time)."""
        steps: list[float] = []
        end = elapsed + length
        while end - elapsed > 1e-9 * dt:
            h = min(max(self.factor, self.growth * elapsed / dt), MAX_TIME_SCALE) * dt
            h = min(h, end - elapsed)
            steps.append(h)
            elapsed += h
        return np.array(steps)


# The start of each fetch hold simulated in real time when the holds are time-scaled: a piece
# still rocks in the clamp, or swings on the lift, for its first tens of ms.
FETCH_HOLD_REALTIME = 0.1  # [s]


def fetch_hold_time_scale(scale: float, clamp_speed: float = 0.0) -> TimeScale | None:
    """The :class:`TimeScale` of a fetch whose holds are scaled by ``scale`` past their first
    ``FETCH_HOLD_REALTIME`` and whose clamp, where slower than ``clamp_speed`` rad/s, is
    run at that speed (None: all in real time; the env's ``fetch_hold_scale`` and
    ``fetch_clamp_speed``)."""
    if scale == 1 and clamp_speed == 0:
        return None
    return TimeScale(float(scale), realtime=FETCH_HOLD_REALTIME,
                     clamp_speed=float(clamp_speed))


@dataclass
class Profile:
    """The commanded motion sampled at every physics step."""

    theta: np.ndarray  # [rad] study angle
    theta_dot: np.ndarray  # [rad/s]
    lift: np.ndarray  # [m] stage displacement from the approach height (+ up)
    lift_dot: np.ndarray  # [m/s]
    phase: np.ndarray  # int codes into PHASES
    step_time: np.ndarray  # [s] physical time each step stands for (dt but in a scaled hold)
    scaled: np.ndarray  # bool: the time-scaled steps (of a slow clamp or a hold)
    t_clamp_start: float
    i_scaled: int | None = None  # the first time-scaled step, of a clamp or hold (None: none)
    tilt: np.ndarray | None = None  # [rad] the pair's roll at each step (None: no roll)


def make_profile(experiment: str, action: FetchAction, dt: float,
                 time_scale: TimeScale | None = None) -> Profile:
    """Piecewise-linear theta(t) and lift(t) of an experiment, at the physics step.

    With ``time_scale`` a hold (the relaxation's; the fetch's hold on the plate and in the
    air) past its first ``time_scale.realtime`` is simulated time-scaled (:class:`TimeScale`):
    one step per entry of ``TimeScale.step_times``; a clamp slower than
    ``time_scale.clamp_speed`` is run at that speed, its steps standing for the rest.
    """
    require(isinstance(action, FetchAction), "action", action, "a FetchAction")
    require_finite("dt", dt)
    require(1e-5 <= dt <= 0.1, "dt", dt, "in [1e-5, 0.1] s")
    require(time_scale is None or isinstance(time_scale, TimeScale), "time_scale", time_scale,
            "a TimeScale or None")
    segments: list[tuple[str, float, float, float]] = []  # (phase, duration, dtheta, dlift)
    scaled: list[tuple[int, np.ndarray]] = []  # (first step, physical time of each step)
    segments.append(("settle", action.settle, 0.0, 0.0))
    _add_clamp(segments, scaled, action, dt,
               0.0 if time_scale is None else time_scale.clamp_speed)
    scale = time_scale if time_scale is not None and time_scale.holds_scaled else None
    if experiment == "fetch":
        _add_hold(segments, scaled, "hold", action.hold, dt, scale)
        segments.append(("lift", action.lift_height / action.lift_speed, 0.0,
                         action.lift_height))
        _add_hold(segments, scaled, "air", action.air_hold, dt, scale)
    elif experiment == "relaxation":
        _add_hold(segments, scaled, "hold", action.hold, dt, scale)
    elif experiment == "slip":
        segments.append(("hold", action.hold, 0.0, 0.0))
        segments.append(("slide", action.slide_time, 0.0, -action.slide_distance))
    else:
        raise InvalidParameterError(f"experiment must be one of {EXPERIMENTS}, got {experiment!r}")
    ends = np.cumsum([s[1] for s in segments])
    n = math.ceil(ends[-1] / dt - 1e-9)
    t = np.arange(n) * dt  # time at the start of each step
    theta = np.zeros(n)
    theta_dot = np.zeros(n)
    lift = np.zeros(n)
    lift_dot = np.zeros(n)
    phase = np.zeros(n, dtype=np.int8)
    th0 = z0 = start = 0.0
    for (name, dur, dth, dz), end in zip(segments, ends, strict=True):
        sel = (t >= start - 1e-12) & (t < end - 1e-12)
        frac = np.clip((t[sel] - start) / dur, 0, 1) if dur > 0 else np.zeros(sel.sum())
        theta[sel] = th0 + dth * frac
        lift[sel] = z0 + dz * frac
        if dur > 0:
            theta_dot[sel] = dth / dur
            lift_dot[sel] = dz / dur
        phase[sel] = PHASE_CODE[name]
        th0, z0, start = th0 + dth, z0 + dz, end
    step_time = np.full(n, dt)
    in_scaled = np.zeros(n, dtype=bool)
    for first, steps in scaled:
        step_time[first:first + steps.size] = steps
        in_scaled[first:first + steps.size] = True
    return Profile(theta, theta_dot, lift, lift_dot, phase, step_time, in_scaled,
                   t_clamp_start=segments[0][1], i_scaled=scaled[0][0] if scaled else None,
                   tilt=_tilt_profile(experiment, action, phase, step_time))


def _tilt_profile(experiment: str, action: FetchAction, phase: np.ndarray,
                  step_time: np.ndarray) -> np.ndarray | None:
    """The roll at the start of every step: 0 until the air hold, then ramped to
    ``action.tilt`` over ``action.tilt_ramp`` physical seconds (None: no roll)."""
    if experiment != "fetch" or not action.tilt:
        return None
    in_air = np.where(phase == PHASE_CODE["air"], step_time, 0.0)
    elapsed = np.cumsum(in_air) - in_air
    return np.where(in_air > 0, tilt_angles(elapsed, action.tilt, action.tilt_ramp), 0.0)


def _add_clamp(segments: list[tuple[str, float, float, float]],
               scaled: list[tuple[int, np.ndarray]], action: FetchAction, dt: float,
               clamp_speed: float) -> None:
    """Append the clamp to ``segments``: in real time, or, where ``action.omega`` is below
    ``clamp_speed``, in steps that each stand for up to ``clamp_speed / omega`` physics
    steps of material time (:class:`TimeScale`); the settle before it is then stretched by
    under a step so that the scaled clamp starts on the step grid."""
    t_clamp = action.theta_d / action.omega
    factor = min(clamp_speed / action.omega, MAX_TIME_SCALE)
    steps = max(1, math.ceil(t_clamp / (factor * dt) - 1e-9)) if factor > 1 else 0
    if steps == 0 or steps >= math.ceil(t_clamp / dt - 1e-9):
        # a clamp at least as fast as clamp_speed, or one so short that rounding its scaled
        # steps up would save none (and make them shorter than dt): in real time
        segments.append(("clamp", t_clamp, action.theta_d, 0.0))
        return
    start = sum(seg[1] for seg in segments)
    first = math.ceil(start / dt - 1e-9)
    name, length, dtheta, dlift = segments[-1]
    segments[-1] = (name, length + first * dt - start, dtheta, dlift)
    segments.append(("clamp", steps * dt, action.theta_d, 0.0))
    scaled.append((first, np.full(steps, t_clamp / steps)))


def _add_hold(segments: list[tuple[str, float, float, float]],
              scaled: list[tuple[int, np.ndarray]], phase: str, length: float, dt: float,
              time_scale: TimeScale | None) -> None:
    """Append a hold of ``length`` physical seconds to ``segments``: with ``time_scale``,
    its first ``time_scale.realtime`` s in real time (ending on the step grid, so at least
    that long) and the rest time-scaled, whose first step and step times go to ``scaled``."""
    if time_scale is None:
        segments.append((phase, length, 0.0, 0.0))
        return
    start = sum(seg[1] for seg in segments)
    first = math.ceil((start + min(time_scale.realtime, length)) / dt - 1e-9)
    realtime = first * dt - start
    segments.append((phase, realtime, 0.0, 0.0))
    steps = time_scale.step_times(realtime, max(length - realtime, 0.0), dt)
    segments.append((phase, steps.size * dt, 0.0, 0.0))
    if steps.size:
        scaled.append((first, steps))


@dataclass
class SimResult:
    """Everything one experiment produced (SI units); :meth:`to_dict` is the JSON form."""

    experiment: str
    action: FetchAction
    scene: dict[str, Any]
    traces: dict[str, np.ndarray]
    pieces: list[dict[str, Any]]
    fetch_rate: float
    fetch_rate_mass: float
    geometry: dict[str, float]
    material: dict[str, Any]
    wall_time: float
    n_steps: int
    timestep: float
    extra: dict[str, Any] = field(default_factory=dict)

    def to_dict(self, traces: bool = True) -> dict[str, Any]:
        out: dict[str, Any] = {
            "experiment": self.experiment,
            "fetch_rate": self.fetch_rate,
            "fetch_rate_mass": self.fetch_rate_mass,
            "pieces": self.pieces,
            "material": self.material,
            "geometry": self.geometry,
            "action": self.action.to_dict(),
            "scene": self.scene,
            "phases": list(PHASES),
            "timestep": self.timestep,
            "n_steps": self.n_steps,
            "wall_time": self.wall_time,
            "extra": self.extra,
        }
        if traces:
            out["traces"] = {k: v.tolist() for k, v in self.traces.items()}
        return out


def material_summary(pieces: tuple[Piece, ...]) -> dict[str, Any]:
    """The true material under the CLI's option names (first piece; all, if they differ)."""
    m = pieces[0].material
    out: dict[str, Any] = {"young": m.young, "poisson": m.poisson, "density": m.density,
                           "g1": m.g1, "tau1": m.tau1, "mu": m.mu, "plate_mu": m.plate_mu,
                           "yield_strain": m.yield_strain, "name": m.name}
    if len({p.material for p in pieces}) > 1:
        out["per_piece"] = [p.material.to_dict() for p in pieces]
    return out


class FetchSimulator:
    """Runs one experiment on one scene.

    Example::

        sim = FetchSimulator(single_block())
        result = sim.run("fetch", FetchAction(theta_d=0.045))
    """

    def __init__(self, pieces: tuple[Piece, ...] | list[Piece],
                 geometry: Geometry | None = None, record_hz: float = 100.0,
                 timestep: float | None = None, impratio: float | None = None,
                 relaxation_contact_ratio: float | None = None,
                 warmstart: Warmstart = "previous") -> None:
        """``timestep`` and ``impratio`` override the scene's (5 ms; impratio 1000 for one
        piece, 100 for several: :data:`fetch_env.scene.MULTI_PIECE_IMPRATIO`) where given.
        ``relaxation_contact_ratio``: how the relaxation experiment stiffens the blades'
        contact with the food (:func:`relaxation_contact_timeconst`).  ``warmstart``: where
        each step's solve starts, "previous" (MuJoCo's: the last step's accelerations) or
        "alternating" (:class:`fetch_env.warmstart.AlternatingWarmstart`, for a stiff clamp
        that rings at the step's period)."""
        require_finite("record_hz", record_hz)
        require(record_hz >= 100, "record_hz", record_hz, ">= 100 Hz")
        if timestep is not None:
            require_finite("timestep", timestep)
            require(1e-4 <= timestep <= 0.02, "timestep", timestep, "in [1e-4, 0.02] s")
        if impratio is not None:
            require_finite("impratio", impratio)
            require(1 <= impratio <= 1e4, "impratio", impratio, "in [1, 1e4]")
        require(isinstance(pieces, tuple | list) and len(pieces) > 0
                and all(isinstance(p, Piece) for p in pieces), "pieces", pieces,
                "a non-empty sequence of Piece")
        require(geometry is None or isinstance(geometry, Geometry), "geometry", geometry,
                "a Geometry or None")
        self.pieces = tuple(pieces)
        self.geometry = geometry or Geometry()
        self.record_hz = record_hz
        self.timestep = timestep
        self.impratio = impratio
        check_relaxation_contact_ratio(relaxation_contact_ratio)
        self.relaxation_contact_ratio = relaxation_contact_ratio
        check_warmstart("warmstart", warmstart)
        self.warmstart = warmstart
        self._scenes: dict[tuple[Geometry, float | None], Scene] = {}

    def scene_for(self, experiment: str) -> Scene:
        """The compiled scene.

        The relaxation probe starts the blades ``RELAXATION_GAP`` from the food (the robot
        closes in until just before contact, as in the study), so that its small theta_d
        (0.0244 rad) is a real squeeze; the slip probe raises the blade tips so they can
        slide down.
        """
        geometry = self.geometry
        piece_timeconst, cube_mesh = None, None
        if experiment == "relaxation":
            timeconst = relaxation_contact_timeconst(self.pieces, geometry,
                                                     self.relaxation_contact_ratio)
            geometry = dataclasses.replace(geometry, gap=min(geometry.gap, RELAXATION_GAP))
            if self.relaxation_contact_ratio is None:
                geometry = dataclasses.replace(geometry, contact_timeconst=timeconst)
            else:
                piece_timeconst, cube_mesh = timeconst, STIFF_CONTACT_CUBE_MESH
        if experiment == "slip":
            # Blade tips at half the lowest piece's centroid height: well below its equator, so
            # the faces grip its widest section and drag it onto the plate (tips above the
            # equator crush a low ellipsoid; a sphere gripped near its equator stick-slips).
            # The blades do not collide with the plate, so the slide may take the tips below it.
            centroid = min(0.5 * float(p.extents[2]) for p in self.pieces)
            geometry = dataclasses.replace(geometry, tip_clearance=max(
                geometry.tip_clearance, 0.5 * centroid))
        key = (geometry, piece_timeconst)
        if key not in self._scenes:
            self._scenes[key] = build_scene(self.pieces, geometry, self.timestep,
                                            self.impratio, piece_timeconst, cube_mesh)
        return self._scenes[key]

    def run(self, experiment: str = "fetch", action: FetchAction | None = None,
            observer: Callable[[mujoco.MjData], None] | None = None,
            time_scale: TimeScale | None = None) -> SimResult:
        """Simulate ``experiment`` with ``action``; validates both before any physics.

        ``observer(data)``, if given, is called at every recorded sample (``record_hz``) with
        the live ``MjData`` (e.g. to render frames); it must not modify it.
        ``time_scale`` (relaxation and fetch): run the holds quasi-statically time-scaled
        (:class:`TimeScale`); the trace is then sampled at every step of a scaled hold.
        """
        require(isinstance(experiment, str) and experiment in EXPERIMENTS, "experiment",
                experiment, f"one of {EXPERIMENTS}")
        require(action is None or isinstance(action, FetchAction), "action", action,
                "a FetchAction or None")
        action = action if action is not None else FetchAction()
        if time_scale is not None:
            require(isinstance(time_scale, TimeScale), "time_scale", time_scale, "a TimeScale")
            require(experiment != "slip" or not time_scale.scaled, "time_scale",
                    time_scale, "not for the slip experiment")
        scene = self.scene_for(experiment)
        return _run(scene, experiment, action, self.record_hz, observer, time_scale,
                    self.warmstart)


def check_relaxation_contact_ratio(ratio: float | None) -> None:
    """Refuse a relaxation contact ratio that is not None or a number in (0, 1000]."""
    if ratio is not None:
        require_finite("relaxation_contact_ratio", ratio)
        require(0 < ratio <= 1e3, "relaxation_contact_ratio", ratio, "in (0, 1000] or None")


def relaxation_contact_timeconst(pieces: tuple[Piece, ...], geometry: Geometry,
                                 ratio: float | None = None) -> float:
    """The contact time constant of the relaxation experiment: ``geometry``'s, made stiffer
    where the food is stiff, so that the contact stays a negligible spring in series with it.

    MuJoCo's contact is a soft constraint in acceleration units: its steady penetration is
    ``(1 - d) / (d k)`` times the unconstrained acceleration at the contact, so the blade-food
    compliance grows as ``1 / (k m)`` for a node of mass ``m``, while the food's stiffness per
    unit mass grows as ``E / (rho s^2)`` (``s``: its thinnest extent).  At the default 10 ms
    the contact is ~100x stiffer than a 0.2 MPa 15 mm cube but comparable to a few-MPa piece
    (a 2 MPa ellipsoid's blade contacts sink 92 um under a 0.4 mm squeeze), which hides part
    of the relaxation (g1 and tau1 came out low on stiff pieces).  So the contact stiffness
    ``1 / tc**2`` is kept at least ``RELAXATION_CONTACT_RATIO * E / (rho s^2)`` for the
    stiffest piece, down to ``tc`` = 1 ms.  On 128 sampled Block scenes (seeds 5000-5127; not
    the held-back ones) the env's probes then gave g1 to a median of ~2.8 % instead of ~4.7 %
    and tau1 (still from the full fit) of ~6.7 % instead of ~10 % (docs/validation/probes.md);
    soft foods (below ~0.3 MPa at 15 mm) keep ``geometry.contact_timeconst``.

    A ``ratio`` (``ProbeConfig.relaxation_contact_ratio``) replaces
    ``RELAXATION_CONTACT_RATIO``, down to ``scene.MIN_PIECE_CONTACT_TIMECONST``: the time
    constant of the pieces' own contact (the blades' with the food), the plate's left as it
    is, and a cube's contact mesh made finer (``scene.STIFF_CONTACT_CUBE_MESH``;
    :meth:`FetchSimulator.scene_for`).  So much stiffer a contact needs a finer step (the
    precise probes' 1 ms) to stay stable.
    """
    stiffness = max(p.material.young / (p.material.density * float(min(p.extents)) ** 2)
                    for p in pieces)
    ratio, floor = ((RELAXATION_CONTACT_RATIO, MIN_CONTACT_TIMECONST) if ratio is None
                    else (ratio, MIN_PIECE_CONTACT_TIMECONST))
    scaled = 1.0 / math.sqrt(ratio * stiffness)
    return float(min(geometry.contact_timeconst, max(scaled, floor)))


def servo_commands(scene: Scene, profile: Profile) -> tuple[np.ndarray, np.ndarray]:
    """Hinge and lift servo targets for every physics step of ``profile``.

    Velocity feed-forward: the servos are kp (q* - q) - kv qdot, so commanding
    q* = q_ref + (kv / kp) qdot_ref makes them track a ramp with no lag.  The target of
    step i is the reference at its end, t_{i+1}.
    """
    n = len(profile.theta)
    ahead = np.minimum(np.arange(n) + 1, n - 1)
    hinge = (scene.pose.theta_open + profile.theta[ahead]
             + SERVO_TIME_CONSTANT * profile.theta_dot[ahead])
    lift = profile.lift[ahead] + SERVO_TIME_CONSTANT * profile.lift_dot[ahead]
    return hinge, lift


def _run(scene: Scene, experiment: str, action: FetchAction, record_hz: float,
         observer: Callable[[mujoco.MjData], None] | None = None,
         time_scale: TimeScale | None = None, warmstart: Warmstart = "previous") -> SimResult:
    """Simulate ``experiment`` on ``scene`` and collect its traces and per-piece outcomes."""
    m = scene.model
    d = initial_state(scene)
    dt = m.opt.timestep
    profile = make_profile(experiment, action, dt, time_scale)
    schedule = _schedule(profile, dt, record_hz)
    prony = PronyRelaxation(scene)
    prony.reset(d)
    n_rec = sum(schedule.record)
    rec = {k: np.zeros(n_rec) for k in ("t", "theta", "theta_cmd", "lift")}
    rec["phase"] = np.zeros(n_rec, dtype=np.int8)
    # the sensors, strain, blade overlap and lowest vertex: raw state in the loop, the
    # meters over batches of samples (recording.py says why)
    recorder = TraceRecorder(scene, d, n_rec)

    def fail(why: str) -> SimulationDivergedError:
        return SimulationDivergedError(f"{why} at t={d.time:.4f} s in {experiment}",
                                       scene.describe(), action.to_dict())

    wall = time.perf_counter()
    try:
        tilt = (None if profile.tilt is None
                else TiltLoad(scene, profile.tilt, 0.5 * action.lift_height,
                                 recorder.positions))
        stall_cap, end_stop = _step_through(scene, d, profile, schedule, prony, recorder, rec,
                                            observer, fail, tilt, warmstart)
    finally:
        prony.restore()  # the model's compiled rest shape, for the next run
    readings, rec["blade_overlap"], le_trace = recorder.finish()  # (timed: part of the run)
    wall = time.perf_counter() - wall
    for k in ("moment", "normal", "tangential"):
        rec[f"{k}_left"], rec[f"{k}_right"] = readings[k].T
    rec["force"] = readings["force"]
    if not np.isfinite(d.qpos).all():
        raise fail("non-finite state")
    warned = {mujoco.mjtWarning(k).name: int(w.number) for k, w in enumerate(d.warning)
              if w.number}
    fetched, passed = _fetched_and_passed(scene, d, recorder, experiment, action)
    pieces_out = _piece_outcomes(scene, d, recorder, rec["phase"], le_trace, fetched, passed)
    rec["max_log_strain"] = le_trace.max(axis=1)
    masses = np.array([p.mass for p in scene.pieces])
    q_open, n, i_scaled = scene.pose.theta_open, len(profile.theta), schedule.i_scaled
    loaded = {} if tilt is None else {"tilt_loaded": np.flatnonzero(tilt.held).tolist()}
    return SimResult(
        experiment=experiment, action=action, scene=scene.describe(), traces=rec,
        pieces=pieces_out, fetch_rate=float(fetched.mean()),
        fetch_rate_mass=float(masses[fetched].sum() / masses.sum()),
        geometry=_geometry_summary(scene), material=material_summary(scene.pieces),
        wall_time=wall, n_steps=n, timestep=dt,
        extra={"t_clamp_start": profile.t_clamp_start, "mujoco_warnings": warned,
               "time_scale": None if time_scale is None else dataclasses.asdict(time_scale),
               "t_scaled": i_scaled * dt if i_scaled < n else None,
               "stalled_at": None if stall_cap == np.inf else float(stall_cap - q_open),
               "max_blade_overlap": float(rec["blade_overlap"].max()),
               # the clamp angle the motor was told in the end: theta_d, or less where the
               # end stop or a stall stopped it
               "theta_d_applied": float(min(action.theta_d, end_stop, stall_cap - q_open)),
               "passed_through": np.flatnonzero(passed).tolist(), **loaded})


@dataclass(frozen=True)
class _Schedule:
    """Which physics steps a run records, and where the time scale of its hold changes.

    The first time-scaled step (of a slow clamp or a hold, if any) is ``i_scaled``; the
    scaled steps' sensors are recorded at every step (each stands for several); the strain,
    blade overlap and lowest vertex, which hardly move in a hold, keep the regular cadence
    (``metered``) and are held between.
    Lists, not arrays: the step loop reads one element at a time, faster from a list.
    """

    i_scaled: int  # first time-scaled step (the step count: none)
    t_physical: list[float]  # [s] physical time at the end of each step
    rescale: dict[int, float]  # step -> the time scale (in physics steps) from there on
    metered: list[bool]  # steps whose strain, overlap and lowest vertex are sampled
    record: list[bool]  # steps recorded in the traces


def _schedule(profile: Profile, dt: float, record_hz: float) -> _Schedule:
    """The recording cadence (``record_hz``) and time-scale changes of ``profile``'s steps."""
    n = len(profile.theta)
    every = max(1, round(1.0 / (record_hz * dt)))
    i_scaled = n if profile.i_scaled is None else profile.i_scaled
    t_physical = np.cumsum(profile.step_time).tolist()
    scale = profile.step_time[i_scaled:] / dt
    changes = np.flatnonzero(np.diff(scale, prepend=np.nan) != 0)
    rescale = dict(zip((i_scaled + changes).tolist(), scale[changes].tolist(), strict=True))
    metered = np.arange(n) % every == 0
    record = (metered | profile.scaled).tolist()
    return _Schedule(i_scaled, t_physical, rescale, metered.tolist(), record)


def _step_through(scene: Scene, d: mujoco.MjData, profile: Profile, schedule: _Schedule,
                  prony: PronyRelaxation, recorder: TraceRecorder, rec: dict[str, np.ndarray],
                  observer: Callable[[mujoco.MjData], None] | None,
                  fail: Callable[[str], SimulationDivergedError],
                  tilt: TiltLoad | None = None,
                  warmstart: Warmstart = "previous") -> tuple[float, float]:
    """Step the physics through ``profile``, filling ``rec`` and ``recorder`` at the
    recorded steps (and loading the held pieces with ``tilt``'s roll, if any), each solve
    started as ``warmstart`` says; returns the hinge angle the motor stalled at (inf: none)
    and the end stop (study angle)."""
    m, ids = scene.model, scene.ids
    dt = m.opt.timestep
    n = len(profile.theta)
    i_scaled, t_physical, rescale = schedule.i_scaled, schedule.t_physical, schedule.rescale
    metered, record = schedule.metered, schedule.record
    q_open = scene.pose.theta_open
    lift_act = ids["servo_lift"]
    hinge_q = [m.jnt_qposadr[ids["hinge_left"]], m.jnt_qposadr[ids["hinge_right"]]]
    dof_left, dof_right = m.jnt_dofadr[ids["hinge_left"]], m.jnt_dofadr[ids["hinge_right"]]
    lift_q = m.jnt_qposadr[ids["lift"]]
    ctrl_hinge, ctrl_lift = servo_commands(scene, profile)
    # Views into MjData, fetched once: attribute access costs more than the arithmetic here.
    qpos, qfrc_constraint, ctrl = d.qpos, d.qfrc_constraint, d.ctrl
    bad_qacc_count = d.warning[int(mujoco.mjtWarning.mjWARN_BADQACC)]
    # Sleeping islands (multi-piece scenes, see scene.py): while every piece sleeps only the
    # robot's dofs are awake, the nodes are frozen, and the relaxation and strain can wait.
    robot_nv = scene.robot_nv
    moved = True  # a piece moved since the last strain sample
    r = 0
    stall_cap = np.inf  # the angle the motor stalled at: the command never goes past it
    # The controller's end stop: the blades never close past CLOSED_MARGIN before their faces
    # meet at the tips (a rigid joint limit there pinched small hard pieces with unbounded
    # force; this way the 2 N m motor is the only thing squeezing).
    end_stop = scene.pose.theta_closed - CLOSED_MARGIN
    ctrl_hinge = np.minimum(ctrl_hinge, q_open + end_stop)
    theta_told = np.minimum(profile.theta, end_stop)  # the angle the motor is told, unstalled
    load = 0.0  # the motor's load moment, low-passed over STALL_TIME (contact impulses pass)
    smooth = 1.0 - math.exp(-dt / STALL_TIME)
    left, right = ids["servo_left"], ids["servo_right"]
    i_tilt = n if tilt is None else tilt.first
    alternating = AlternatingWarmstart(m.nv) if warmstart == "alternating" else None
    for i in range(n):
        if i in rescale:
            prony.set_time_scale(rescale[i])
        if i >= i_tilt:
            tilt.step(d, i)  # type: ignore[union-attr]
        # (two scalar reads: cheaper than a numpy reduction over a two-value gather)
        load += smooth * (max(abs(qfrc_constraint[dof_left]), abs(qfrc_constraint[dof_right]))
                          - load)
        if stall_cap == np.inf and load > STALL_MOMENT:
            # A real clamping motor cannot push harder than its stall moment: the blades
            # stop where they are (stiff pieces are held, not crushed).
            stall_cap = 0.5 * (qpos[hinge_q[0]] + qpos[hinge_q[1]])
        ctrl[left] = ctrl[right] = min(ctrl_hinge[i], stall_cap)
        ctrl[lift_act] = ctrl_lift[i]
        asleep = d.nv_awake == robot_nv
        prony.apply(d, asleep)
        if alternating is not None:
            alternating.before_step(d)
        mujoco.mj_step(m, d)
        if alternating is not None:
            alternating.after_step(d)
        moved = moved or not (asleep and d.nv_awake == robot_nv)
        if bad_qacc_count.number:  # autoreset is off: the state is still the bad one
            raise fail("bad or non-finite acceleration")
        if record[i]:
            # physical time: the scaled hold's steps stand for several steps each
            rec["t"][r] = d.time if i < i_scaled else t_physical[i]
            rec["phase"][r] = profile.phase[i]
            rec["theta"][r] = 0.5 * (qpos[hinge_q[0]] + qpos[hinge_q[1]]) - q_open
            # what the motor is told: the profile within the end stop, held where it stalled
            rec["theta_cmd"][r] = min(theta_told[min(i + 1, n - 1)], stall_cap - q_open)
            rec["lift"][r] = qpos[lift_q]
            # (step 0 is metered, and its strain fresh)
            fresh = metered[i] and (moved or r == 0)
            recorder.sample(metered[i], fresh)
            if fresh:
                moved = False
            if observer is not None:
                observer(d)
            r += 1
    return stall_cap, end_stop


def _fetched_and_passed(scene: Scene, d: mujoco.MjData, recorder: TraceRecorder,
                        experiment: str, action: FetchAction) -> tuple[np.ndarray, np.ndarray]:
    """Per piece at the end of a run: fetched (lifted and between the blades, fetch only)
    and passed through a blade or the plate (never counted fetched)."""
    low, centre = recorder.positions(d)
    half_gap = _blade_half_gap(scene, d)
    stage_y = scene.pose.stage_xy[1]
    if experiment == "fetch":
        fetched = (low > 0.5 * action.lift_height) & (np.abs(centre[:, 1] - stage_y) < half_gap)
        if action.tilt:  # and not slid off the blades' ends along the hinge axis
            fetched &= (np.abs(centre[:, 0] - scene.pose.stage_xy[0])
                        < 0.5 * scene.geometry.blade_width)
    else:
        fetched = np.zeros(len(scene.pieces), dtype=bool)
    # Passed through: a vertex got beyond a blade's or the plate's far face.  A very soft piece
    # squeezed hard can get there (a blade's edge cuts into it and MuJoCo's box contact, past
    # the mid-plane, pushes the vertex out of the far side), which a one-cell flex cannot
    # represent: its LE is then no measurement and the piece is not really held, so it is
    # reported as passed through and never counted fetched.  (A firm clamp's blade edge can
    # indent a piece 2 mm deep without that: measured on a Block scene, LE 0.24, held.)
    plate_thickness = 2.0 * float(scene.model.geom_size[scene.ids["plate"]][2])
    passed = ((recorder.max_overlap > 2.0 * BLADE_HALF_THICKNESS)
              | (recorder.lowest_z < -plate_thickness))
    fetched &= ~passed
    return fetched, passed


def _piece_outcomes(scene: Scene, d: mujoco.MjData, recorder: TraceRecorder,
                    phase: np.ndarray, le_trace: np.ndarray, fetched: np.ndarray,
                    passed: np.ndarray) -> list[dict[str, Any]]:
    """Each piece's outcome: fetched, the largest strain in the clamp and in the lift, where
    it ended, and how deep it went into the plate and the blades."""
    low, centre = recorder.positions(d)
    dt = scene.model.opt.timestep
    in_clamp = np.isin(phase, [PHASE_CODE["clamp"], PHASE_CODE["hold"], PHASE_CODE["slide"]])
    in_lift = np.isin(phase, [PHASE_CODE["lift"], PHASE_CODE["air"]])
    plastic = residual_plastic_strain(scene, d)
    pieces_out = []
    for k, p in enumerate(scene.pieces):
        pieces_out.append({
            "shape": p.shape, "size": p.size, "mass": p.mass, "young": p.material.young,
            "young_simulated": simulated_young(p, dt),
            "fetched": bool(fetched[k]),
            "max_log_strain_clamp": float(le_trace[in_clamp, k].max()) if in_clamp.any() else 0.0,
            "max_log_strain_lift": float(le_trace[in_lift, k].max()) if in_lift.any() else 0.0,
            "residual_plastic_strain": plastic[k],
            "final_centre": centre[k].tolist(),
            "final_lowest_z": float(low[k]),
            "lowest_z_ever": float(recorder.lowest_z[k]),
            "max_blade_overlap": float(recorder.max_overlap[k]),
            "passed_through": bool(passed[k]),
        })
    return pieces_out


def _geometry_summary(scene: Scene) -> dict[str, Any]:
    """The clamp pose and the end-effector's sizes, as a result reports them."""
    return {**scene.pose.to_dict(),
            "blade_length": scene.geometry.blade_length,
            "blade_width": scene.geometry.blade_width,
            "tip_clearance": scene.geometry.tip_clearance, "gap": scene.geometry.gap}


def _blade_half_gap(scene: Scene, d: mujoco.MjData) -> float:
    """Half the distance between the blades' inner faces at the food's centroid height."""
    q = d.qpos[scene.model.jnt_qposadr[scene.ids["hinge_left"]]]
    return scene.pose.face_y(q, scene.pose.L) + 1e-3
