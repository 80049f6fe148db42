"""The probes' settings (:class:`ProbeConfig`) and the repeats they imply: the squeezes
of the relaxation clamps (:func:`repeat_strains`) and the durations of the slides
(:func:`slide_times`)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Literal

import numpy as np

# how the slip probe's envelope reads the half-spoons' force ratios (ProbeConfig.slip_envelope),
# each kind with the evidence it was chosen on, and mu's systematic sd
from estimators.slip_level import MU_SYSTEMATIC_SD, SLIP_ENVELOPES, SlipEnvelope
from fetch_env.controller import check_relaxation_contact_ratio
from fetch_env.errors import require, require_finite, require_type
from fetch_env.layouts import Piece
from fetch_env.scene import Geometry
from fetch_env.warmstart import Warmstart, check_warmstart

PARAM_NAMES: tuple[str, ...] = ("K1", "K2", "B", "mu", "g1", "tau1")


# The probes' systematic uncertainty (sd of the log estimate, beyond what each trace reveals),
# by parameter: for each tuning food of the validation harness (benchmarks/
# validate_estimators.py --set tuning, seed fetch_env.food_space.TUNING_SEED, never the
# reporting foods) the least sd that puts the truth inside the 95 % interval, and of those
# the 95th percentile (benchmarks/validate_estimators.py --calibrate).  So the intervals
# cover the truth on 95 % of the tuning foods by construction; the reporting foods say
# whether that holds on foods they were not chosen on.
# Computed on 64 tuning foods with the "measure" probes, calibrated, with no added noise
# and with 1 % noise, the larger of the two, rounded up: g1 and tau1 need little beyond their
# own window-shift and noise parts, mu 2 % with noise (its envelope then reads noise peaks),
# the springs a tenth.  Where a calibration has an error model (the shipped ones do), it
# sets the intervals of g1, tau1 and mu instead (apply_calibration), and, where it has a
# K1 + K2 part (the "repeated" one), those of K1, K2 and B; these sds hold for the rest and
# for uncalibrated probes.
PROBE_SYSTEMATIC_SD: dict[str, float] = {"K1": 0.14, "K2": 0.10, "B": 0.11, "g1": 0.010,
                                         "tau1": 0.004, "mu": MU_SYSTEMATIC_SD}




# Where K1, K2 and B take the clamp's first-contact angle from (ProbeConfig.contact_angle):
# the full fit's (the moment's rise) or the depth camera's view of the piece's rest surface
# (first_contact_angle, the angle the clamp is set from).
ContactAngle = Literal["fit", "camera"]
CONTACT_ANGLES: tuple[ContactAngle, ...] = ("fit", "camera")

MAX_RELAXATION_REPEATS = 15
MAX_SLIP_REPEATS = 9


# The slide-time ratio between the slip probe's successive slides (slide_times).
SLIP_REPEAT_TIME_RATIO = 1.5


@dataclass(frozen=True)
class ProbeConfig:
    """Settings of the two reset probes (SI units).

    Attributes:
        strain: squeeze of the relaxation probe beyond first contact, as a share of the
            piece's width [-] (each face travels ``strain * width / 2`` past the surface).
        omega: clamping angular velocity of the relaxation probe [rad/s].
        hold: relaxation hold [s]; the accuracy of g_1 and tau_1 grows with it (it should
            be of the order of tau_1), and so does the probe's cost.
        settle: settling time on the plate before each probe's clamp [s].
        slip_strain: squeeze of the slip probe beyond first contact [-].
        slip_omega: clamping angular velocity of the slip probe [rad/s] (fast: its clamp
            is only the approach to the slide).
        slip_hold: hold before the slide [s].
        slide_distance: induced-slip travel toward the plate [m].
        slide_time: duration of the induced slip [s].
        hold_time_scale: the relaxation hold past its first ``HOLD_SETTLE`` is simulated
            this many times faster, quasi-statically (:class:`fetch_env.controller.
            TimeScale`); 1 simulates it in real time.
        hold_time_growth: each scaled step of the relaxation hold stands for at least this
            share of the hold's elapsed time (log-spaced steps, ``TimeScale.growth``).
        relaxation_impratio: MuJoCo's ``impratio`` in the relaxation probe's scene (the base
            scene's is 1000, which makes friction nearly Coulomb for the fetch and the slip).
            The held piece must not creep, but 30 is enough for that and halves the Newton
            iterations of each step (see the module docstring).
        slip_timestep: the slip probe's physics step [s] (the base scene's is 5 ms).
        slip_envelope: how mu's envelope reads the two half-spoons' force ratios, "sum" (of
            their summed forces), "per_blade" (the lower of their own envelopes) or
            "per_blade_denoised" (those less what sensor noise adds) or
            "per_blade_slipping" (those refined to the level the ratio slips at) or
            "per_blade_simex" (that level less the bias noise leaves in it, extrapolated
            away; see :data:`SLIP_ENVELOPES`).
        slip_gap: the slip probe's clearance between each blade face and the food at the
            open pose [m]; None keeps the geometry's (1 mm).  The blades close by turning
            about the hinge, so at the slip's clamp angle their faces lean in by that angle
            while a cube's sides stand upright: the blade tip's edge presses into the side,
            and its contacts' normals, the side's, lean from the blade's by the clamp angle,
            so their push reads as friction in the blade's frame (mu + angle (1 + mu^2)).
            A smaller gap and squeeze need a smaller angle (see the ``precise`` preset).
        relaxation_timestep: the relaxation probe's physics step [s]; None keeps the base
            scene's 5 ms.  Under MuJoCo's ``discrete`` integrator the blade contact's
            compliance grows with the step (a 10 mm, 3 MPa ellipsoid's blades sink 39 um at
            5 ms, 13 um at 2.5 ms, 4.6 um at 1 ms), and that compliance, in series with the
            food, lengthens the held moment's relaxation time by ``K2 / (K1 + k_c)``.
        relaxation_repeats: how many relaxation clamps to run, each at its own squeeze
            (:func:`repeat_strains`); g_1 and tau_1 are the medians over the clamps.  The
            simulated clamp is chaotic in its squeeze (some foods clamped a few per cent
            deeper read another tau_1; ``docs/estimator_validation.md``, "Seven clamps at
            nearby squeezes"), so a median over nearby squeezes shrinks the tails, at the
            cost of one probe per clamp.
        repeat_strain_step: the relative strain step between the repeated clamps [-].
        slip_repeats: how many slip probes to run, each a fresh clamp and slide over
            ``slide_distance``, alternately slower and faster (:func:`slide_times`); mu is
            their median.  Coulomb friction does not depend on the sliding speed, but where
            a stick-slipping piece's slips fall does, and a single slide's envelope is
            chaotic in it (a few per cent off on some foods); the median of three slides
            misses by more than 1.4 % on fewer foods (the ``precise`` preset), and their
            spread (diagnostic ``mu_trials``) says which foods to trust less.
        contact_angle: the first-contact angle that turns the held moment into K1, K2 and B
            through eq. 7 and times the clamp for g_1 and tau_1: "fit" (the full fit's,
            from the moment's rise) or "camera" (:func:`first_contact_angle`, the piece's
            rest surface as a depth camera sees it, from which the clamp angle is set; the
            truth's angle, :func:`elastic_stiffness`).  The squeeze past first contact is a
            few per cent of the piece's width, so a fitted angle a little off moves K1 + K2
            by much more: on 156 tuning foods (``measure`` probes, uncalibrated) K1 + K2 was
            within 6.6 / 39 % (median / 95th percentile) with the fit's angle and 1.2 / 9.2 %
            with the camera's; g_1 2.4 / 11.6 % and 2.3 / 11.6 %, tau_1 unchanged.
        relaxation_contact_ratio: None stiffens every contact of the relaxation scene at
            ``controller.RELAXATION_CONTACT_RATIO`` times the food's ``E / (rho s^2)``, down
            to a 1 ms time constant; a ratio stiffens only the blades' contact with the
            piece, at that ratio, down to 20 us, leaves the plate's (a stiff plate contact
            launches a resting piece) and gives a cube a finer contact mesh (its flat face
            chatters under so stiff a contact on the coarse one:
            ``scene.STIFF_CONTACT_CUBE_MESH``).  A contact in series with the food
            lengthens the held moment's decay (``tau1 (1 + K2 / (K1 + k_c))``), so the
            stiffer it is the closer the hold is to the food's own relaxation; it needs a
            fine step (``relaxation_timestep``) to stay stable (the ``precise`` preset).
        relaxation_warmstart: where each step's solve of the relaxation clamp starts
            (:mod:`fetch_env.warmstart`): "previous", MuJoCo's own, or "alternating", which
            follows a held food that rings at the step's period under so stiff a contact
            and takes fewer Newton iterations a step there (the ``precise`` preset).
    """

    strain: float = 0.06
    omega: float = 0.1
    hold: float = 6.0
    settle: float = 0.05
    slip_strain: float = 0.1
    slip_omega: float = 0.4
    slip_hold: float = 0.05
    slide_distance: float = 0.002
    slide_time: float = 0.15
    hold_time_scale: float = 8.0
    hold_time_growth: float = 0.05
    relaxation_impratio: float = 30.0
    slip_timestep: float = 0.01
    relaxation_timestep: float | None = None
    slip_envelope: SlipEnvelope = "sum"
    relaxation_repeats: int = 1
    repeat_strain_step: float = 0.02
    contact_angle: ContactAngle = "fit"
    relaxation_contact_ratio: float | None = None
    slip_gap: float | None = None
    slip_repeats: int = 1
    relaxation_warmstart: Warmstart = "previous"

    def __post_init__(self) -> None:
        for name, (lo, hi, lo_open) in _PROBE_LIMITS.items():
            value = getattr(self, name)
            require_finite(name, value)
            ok = (lo < value if lo_open else lo <= value) and value <= hi
            require(ok, name, value, f"in {'(' if lo_open else '['}{lo:g}, {hi:g}]")
        if self.relaxation_timestep is not None:
            require_finite("relaxation_timestep", self.relaxation_timestep)
            require(1e-4 <= self.relaxation_timestep <= 0.02, "relaxation_timestep",
                    self.relaxation_timestep, "in [1e-4, 0.02] s or None")
        if self.slip_gap is not None:
            require_finite("slip_gap", self.slip_gap)
            require(0 <= self.slip_gap <= 0.01, "slip_gap", self.slip_gap,
                    "in [0, 0.01] m or None")
        require(isinstance(self.relaxation_repeats, int | np.integer)
                and not isinstance(self.relaxation_repeats, bool)
                and 1 <= self.relaxation_repeats <= MAX_RELAXATION_REPEATS,
                "relaxation_repeats", self.relaxation_repeats,
                f"an integer in [1, {MAX_RELAXATION_REPEATS}]")
        require(isinstance(self.slip_repeats, int | np.integer)
                and not isinstance(self.slip_repeats, bool)
                and 1 <= self.slip_repeats <= MAX_SLIP_REPEATS,
                "slip_repeats", self.slip_repeats, f"an integer in [1, {MAX_SLIP_REPEATS}]")
        require_finite("repeat_strain_step", self.repeat_strain_step)
        require(0.0 <= self.repeat_strain_step <= 0.2
                and self.relaxation_repeats // 2 * self.repeat_strain_step < 1.0,
                "repeat_strain_step", self.repeat_strain_step,
                "in [0, 0.2], with every repeated clamp's strain above 0")
        require(isinstance(self.slip_envelope, str) and self.slip_envelope in SLIP_ENVELOPES,
                "slip_envelope", self.slip_envelope, f"one of {SLIP_ENVELOPES}")
        require(isinstance(self.contact_angle, str) and self.contact_angle in CONTACT_ANGLES,
                "contact_angle", self.contact_angle, f"one of {CONTACT_ANGLES}")
        check_relaxation_contact_ratio(self.relaxation_contact_ratio)
        check_warmstart("relaxation_warmstart", self.relaxation_warmstart)


# ProbeConfig's settings: name -> (low, high, low end excluded)
_PROBE_LIMITS: dict[str, tuple[float, float, bool]] = {
    "strain": (0.0, 0.5, True), "omega": (1e-3, 2.0, False), "hold": (0.0, 600.0, False),
    "settle": (0.05, 5.0, False), "slip_strain": (0.0, 0.5, True),
    "slip_omega": (1e-3, 2.0, False), "slip_hold": (0.0, 600.0, False),
    "slide_distance": (0.0, 0.02, True), "slide_time": (0.0, 120.0, True),
    "hold_time_scale": (1.0, 50.0, False), "hold_time_growth": (0.0, 0.5, False),
    "relaxation_impratio": (1.0, 1e4, False), "slip_timestep": (1e-4, 0.02, False),
}


def repeat_strains(config: ProbeConfig) -> list[float]:
    """The squeezes of the relaxation clamps: ``strain`` first, then alternately below and
    above it by ``repeat_strain_step`` of it, ``strain * (1, 1 - s, 1 + s, 1 - 2 s, ...)``."""
    return [config.strain * (1.0 - m * config.repeat_strain_step)
            for m in _alternating_steps(config.relaxation_repeats)]


def _alternating_steps(n: int) -> list[int]:
    """``n`` signed step counts of repeats around a first setting: 0, 1, -1, 2, -2, ..."""
    return [(j + 1) // 2 * (1 if j % 2 else -1) for j in range(n)]


def slide_times(config: ProbeConfig) -> list[float]:
    """The durations of the slip probe's slides: ``slide_time`` first, then alternately
    slower and faster by :data:`SLIP_REPEAT_TIME_RATIO`, ``slide_time * (1, r, 1 / r, r^2,
    1 / r^2, ...)``."""
    return [config.slide_time * SLIP_REPEAT_TIME_RATIO ** m
            for m in _alternating_steps(config.slip_repeats)]


def _check_probe_args(piece: Any, config: Any, geometry: Any) -> None:
    """Refuse a piece (where given) that is not a ``Piece``, a config that is not a
    ``ProbeConfig`` and a geometry that is not a ``Geometry`` or None."""
    if piece is not None:
        require_type("piece", piece, Piece, "a Piece")
    require_type("config", config, ProbeConfig, "a ProbeConfig")
    require_type("geometry", geometry, Geometry | None, "a Geometry or None")
