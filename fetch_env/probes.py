"""The probes an environment runs at reset, and the true values they are held against.

At reset the robot probes one piece (the one nearest the layout's centre, the piece it will
clamp first) with two short experiments on the simulated sensors:

* a gentle clamp and a hold (the ``relaxation`` experiment: the blades start
  ``RELAXATION_GAP`` = 0.1 mm from the food) whose moment trace (mean of both blades, clamp
  and hold samples, t from the clamp start) feeds :func:`estimators.estimate_full_fit`
  (falling back to the study's three-step method) for the contact angle, and
  :func:`estimators.estimate_from_hold` (the hold alone, past ``HOLD_SETTLE``) for K1, K2,
  B, g_1 = K2 / (K1 + K2) and tau_1 = B / K2;
* an induced slip (the ``slip`` experiment, a short fast slide) whose contact forces feed
  :func:`estimators.estimate_friction` and the upper envelope of the force ratio (Coulomb
  bounds the ratio by mu; a stick-slipping slide reaches it only while slipping), giving mu.

The probe piece is simulated alone (a camera tells the robot where it is, and the probe's
cost must not grow with the number of pieces).  The clamp angle of each probe is set from
what a depth camera over the plate would see before any touch: the angle at which the blade
faces first reach the piece's actual surface (the compiled mesh's rest vertices, see
:func:`first_contact_angle`; for spheres and ellipsoids the mesh lies up to ~1 mm inside
the nominal shape, so the nominal width would miss the piece), plus the angle that
squeezes the piece by ``strain`` of its width: the same gentle squeeze for every shape.

Accuracy against time (measured on sampled Block scenes, see ``docs/validation/probes.md`` and
``tests/test_env_slow.py``): the hold must be of the order of tau_1 (1 to 6 s) for g_1 and
tau_1 to be identified: over a hold h << tau_1 the decay is linear to within
(h / tau_1)^2 / 2 and only the ratio g_1 / tau_1 shows.  The default hold is 6 s, simulated
quasi-statically time-scaled past its first ``HOLD_SETTLE``
(:class:`fetch_env.controller.TimeScale`): each step stands for at least 8 physical steps
and at least 5 % of the hold's elapsed time, so the samples are log-spaced, as a relaxation
test records them, and the 6 s cost ~60 steps past the first 0.25 s.  Three settings make the
probes cheap (on seeds 5000-5191, |error| median / 75th / 95th percentile, and
the probes' wall time per reset on this project's 2-core VM):

* without them (a constant 8x hold, impratio 1000, slip at 5 ms): mu 0.1 / 1.0 /
  4.9 %, g_1 2.4 / 5.1 / 10.1 %, tau_1 4.9 / 9.7 / 25 %; 244 ms;
* ``relaxation_impratio`` 30 (impratio sets how stiff friction is against the normal force;
  at one held state MuJoCo's Newton solver took 12-13 iterations a step at 1000, 9-10 at
  100 and 5-6 at 10, 455 / 350 / 255 us a step): with the other two settings, 100 gave
  tau_1 3.5 / 6.4 / 17 %, 30 2.4 / 5.9 / 15 %, and 10 let stiff pieces creep (tau_1 errors
  up to 330 %);
* log-spaced steps (``hold_time_growth`` 0.05): ~66 scaled steps instead of 144;
* the slip probe at a 10 ms step (``slip_timestep``): mu as at 5 ms (0.1 / 1.2 / 4.6 %) for
  half the steps; the relaxation probe at 10 ms was worse (tau_1 median 9 % on 64 seeds).

Together: mu 0.1 / 1.2 / 4.6 %, g_1 3.4 / 6.6 / 12 %, tau_1 2.4 / 5.9 / 15 %; 113 ms.  g_1 is
a point worse because stiff pieces (E > 1 MPa) come out lower: mean -8 % (-5 % before; soft
ones -1 % both times; the contact in series with them, see
:func:`fetch_env.controller.relaxation_contact_timeconst`); tau_1 is better.  A faster
relaxation clamp (0.2 rad/s) saved 20 steps but moved g_1's 95th percentile to 15 %.  The
slip probe's 0.15 s slide, sampled at every 10 ms step, gives estimate_friction its
samples; its fast clamp (0.4 rad/s) is stable and saves ~0.2 s; the relaxation clamp stays at
0.1 rad/s.

The oracle values are the material's g_1, tau_1 and mu exactly, and nominal spring constants
for K1, K2 and B from the piece's size (see :func:`true_parameters`).
"""

from __future__ import annotations

import dataclasses
import functools
import json
import math
import os
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

import numpy as np

from estimators import (
    ClampGeometry,
    EstimationError,
    HoldEstimate,
    SLSParams,
    ViscoelasticEstimate,
    estimate_friction,
    estimate_from_hold,
    estimate_full_fit,
    estimate_three_step,
)
from estimators.calibration import ERROR_TARGETS, Calibration
from estimators.uncertainty import (
    DRIFT_DIAGNOSTICS,
    MAX_LOG_HALF_WIDTH,
    Z95,
    hold_with_intervals,
    log_interval,
)
from estimators.uncertainty import drift_diagnostics as uncertainty_drift
from fetch_env.controller import (
    PHASE_CODE,
    RELAXATION_GAP,
    FetchAction,
    FetchSimulator,
    SimResult,
    TimeScale,
    check_relaxation_contact_ratio,
)
from fetch_env.errors import (
    InvalidParameterError,
    SimulationDivergedError,
    require,
    require_finite,
    require_int,
    require_pieces,
    require_type,
)
from fetch_env.layouts import Piece
from fetch_env.parallel import Task, outcome, run_ahead
from fetch_env.scene import Geometry, Scene, initial_state
from fetch_env.slip_simex import LevelRule, Simex, simex_level, slipping_shift
from fetch_env.spaces import VISCO_NAMES

PARAM_NAMES: tuple[str, ...] = ("K1", "K2", "B", "mu", "g1", "tau1")
HOLD_SKIP = 0.1  # [s] start of the relaxation hold left out of the fit (servo catching up)
# [s] start of the hold left out of the hold-only fit of g1 and tau1: a round piece that rocks
# as the blades close is still settling into the clamp (its moment rising, then falling faster
# than the material relaxes) up to ~0.25 s after t_d.  On seeds 5000-5063, 0.2 / 0.25 / 0.3 s
# gave g1 median errors of 6.1 / 5.5 / 5.3 % and 75th percentiles of 12.8 / 12.3 / 13.1 %;
# for tau1 on seeds 5000-5127, 0.1 / 0.25 / 0.5 / 0.75 s gave
# medians of 6.5 / 5.9 / 6.0 / 7.2 % and 75th percentiles of 13.2 / 11.6 / 11.8 / 15.3 %.
HOLD_SETTLE = 0.25
CLAMP_WEIGHT = 0.3  # full fit: clamp residuals against the hold (docs/reproducing.md)
# A 95 % interval of g1, tau1 or mu wider than +-2.5 % makes an outcome unreliable.  With the
# calibration's error model giving the intervals (estimators.calibration.ErrorModel), this is
# about the widest that calls no tuning food reliable whose g1, tau1 or mu error exceeds 5 %:
# on the 256 tuning foods ("measure" probes, cross-validated) the narrowest such food's
# half-width was 2.2-5.0 % without noise, by how the folds fell (8-fold seed 0: 5.0 %; 4-fold
# seeds 1-3: 2.8, 3.5, 2.2 %; 8-fold seeds 1, 2: 2.6, 4.4 %), and 5.5-7.2 % with 1 % noise.
# The price: of the foods whose errors were all under 2 %, only about 3 of 77 (no noise) and
# none of 33 (1 % noise) have intervals that narrow (15 of 77 at 3.5 %).  What is left after
# the calibration is a per-food bias (the contact's compliance, the plate, the bulge) that
# the diagnostics predict only roughly, so an interval that must cover it cannot be narrow;
# a flag that never calls a 5 % miss reliable is then rarely True.  A calibration's error
# model may carry its own widths, chosen on its own tuning foods
# (estimators.calibration.ErrorModel.reliable_half_width; the "precise" probes', see
# benchmarks/validate_estimators.py RELIABILITY, which also limits the repeats' spread).
RELIABLE_HALF_WIDTH = 0.025
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
                                         "tau1": 0.004, "mu": 0.02}
# slip probe: quantile of |F_t| / F_n taken as mu where the plateau is lower.  Coulomb bounds
# the ratio by mu and a stick-slipping piece reaches it only in its short slips, so a high
# quantile: on the 64 tuning foods ("measure" probes) 0.95 / 0.99 / 1.0 gave mu's median
# error 0.52 / 0.30 / 0.23 % and 95th percentile 7.0 / 5.2 / 5.2 %; 0.99, not the maximum,
# so that sensor noise cannot set it.
ENVELOPE_QUANTILE = 0.99
# How the slip probe's envelope reads the two half-spoons (ProbeConfig.slip_envelope):
# "sum": the ratio of their summed forces; "per_blade": each half-spoon's own ratio, and the
# lower of the two envelopes, and likewise the lower of the two faces' plateaus.  Coulomb
# bounds each half-spoon's ratio by mu, and each reaches it whenever its own face slips, so
# the lower one reads mu unless both faces misread together.  What makes one face misread: a
# blade tip ploughing into a cube's face as the blades slide (a few contacts on the tip's
# edge, whose normal is tilted ~50 degrees from the face's, add their push to the tangential
# force; measured contact by contact on a 9 mm, 0.024 MPa cube whose summed ratio read mu
# +45 %).  Chosen on the 256 tuning foods (the committed uncalibrated "measure" runs, median /
# 95th percentile of |mu error|): "sum" 0.26 / 8.04 %, "per_blade" 0.09 / 4.09 % without
# noise; 2.06 / 9.46 % and 2.17 / 5.42 % with 1 % noise.  A lower quantile, the per-sample
# lower face, or smoothing the forces first did worse on the 95th percentile.
# "per_blade_denoised": per_blade's envelopes, each less the share of it that sensor noise
# adds: a ratio that sits at mu with white noise of sd s per sample has its
# ENVELOPE_QUANTILE quantile at mu + NOISE_QUANTILE_Z s, so that is taken off, with s from
# each half-spoon's force noise before the blades touch (the settle phase, where the true
# forces are zero; :func:`_settle_noise`).  Without noise it reads exactly as per_blade.  On
# the 512 tuning foods with 1 % noise (the "precise" slip probe) it moved mu's |error| from
# 3.7 / 14.5 % (median / 95th percentile; mean +4.8 %) to 1.8 / 8.6 % (mean -0.1 %).
# "per_blade_slipping": per_blade_denoised's envelope, refined to the level the ratio sits
# at while the face slips, read from every sample near it instead of one quantile: with
# noise the ratio's top samples are the slipping ones, spread by the noise (sd s) about mu,
# so mu is the mean of the samples above (mu - SLIPPING_TAIL s) less that truncated
# normal's shift (s phi(c) / Phi(c), c = SLIPPING_TAIL), iterated from the denoised
# envelope.  Without noise (s = 0) it reads exactly as per_blade.  On the 512 tuning foods
# with 1 % noise (benchmarks/slip_probe.py), mu's |error| (median / 90th / 95th percentile /
# max) from the precise probe's three slides went from 1.50 / 4.5 / 5.6 / 16 % to 0.77 /
# 2.8 / 4.1 / 19 % (foods past 1.4 %: 261 to 136; both read from every gripping sample,
# before NOISY_SLIP_MIN_SHARE); from one slide alone from 1.80 / 6.0 /
# 8.6 % to 0.95 / 6.3 / 11.6 %: a single slide's level misreads a few more foods badly,
# which the median of three mends.  On 256 of them, four noise draws each (three slides),
# with 1 % noise 1.50 / 4.5 / 5.9 % went to 0.76 / 3.0 / 4.9 %, with 0.3 %
# from 0.66 / 1.7 / 2.2 % to 0.33 / 1.2 / 1.8 %, with
# 3 % from 3.5 / 12 / 16 % to 1.7 / 6.6 / 9.4 % (the worst 76 % against 45 %; two draws
# each); c = 1.25 / 1.75 gave 0.73 / 2.9 / 6.8 % and 0.83 / 3.0 / 4.2 % with 1 % noise;
# smoothing the forces first biased mu low instead (mean -1.6 to -4.8 %).
# "per_blade_simex": per_blade_slipping's level less the bias that sensor noise puts into
# it, measured on the trace by simulation-extrapolation (fetch_env.slip_simex): copies of
# the slide with more noise of the sensor's own kind read lower, and their levels,
# extrapolated linearly in the noise's sd back to none, give the noise-free level.  Without
# noise it reads exactly as per_blade_slipping (and so as per_blade).  Chosen on the 512
# tuning foods' slides (precise probe, three slides, one 1 % noise draw each,
# uncalibrated; median / 90th / 95th percentile / max of |mu error|, mean, foods past
# 1.4 %): the slipping level 0.82 / 2.5 / 3.2 / 6.3 %, -1.1 %, 162; extrapolated from
# lambda 0.5, 1, 1.5 and 2 with 10 copies each 0.47 / 1.5 / 1.9 / 4.1 %, -0.36 %, 62; from
# lambda 1 and 3 with 5 or 10 copies 0.47 / 1.6 / 2.0 / 4.4 % and 0.42 / 1.5 / 1.9 / 4.3 %;
# extrapolated linearly in lambda instead of the sd 0.69 / 1.9 / 2.7 / 5.0 % (first 60
# foods, two draws: the bias grows with the sd, not the variance).  On the first 128 with
# 0.3 % noise 0.40 / 1.0 / 1.3 / 2.7 % went to 0.24 / 0.8 / 1.0 / 5.3 % (the 5.3 % a
# slippery cube whose noise-free reading is itself 1-6 % high: the extrapolation recovers
# the noise-free reading, not mu), with 3 % from 1.6 / 7.0 / 8.3 / 11.6 % (21 foods past
# 5 %) to 1.1 / 3.9 / 5.2 / 9.4 % (7 past 5 %).  With benchmarks/slip_probe.py's noise
# draws (512 tuning foods, 1 %): 0.87 / 2.7 / 3.1 / 6 %, mean -1.11 %, 154 foods past 1.4 %
# went to 0.44 / 1.5 / 2.0 / 4 %, -0.22 %, 55.
SlipEnvelope = Literal["sum", "per_blade", "per_blade_denoised", "per_blade_slipping",
                       "per_blade_simex"]
SLIP_ENVELOPES: tuple[SlipEnvelope, ...] = ("sum", "per_blade", "per_blade_denoised",
                                            "per_blade_slipping", "per_blade_simex")
SLIP_SIMEX = Simex()
NOISE_QUANTILE_Z = 2.326  # the standard normal's ENVELOPE_QUANTILE (0.99) quantile
SLIPPING_TAIL = 1.5  # [noise sds] below the slipping level still read as slipping
SLIPPING_ITERATIONS = 5
# With sensor noise the noise-aware envelopes read only the samples where both half-spoons
# press with at least this share of their largest normal force over the late slide.  A
# ratio's noise grows as 1 / F_n, and a round piece that bounces between the blades passes
# through normal forces near zero many times a slide (a 16 mm sphere's: 0 to 0.7 N every
# ~15 ms, its ratio at mu throughout); its weakly pressed samples' noise is several times
# the median sd the envelope takes off, so their top read mu high (+16 %).  Chosen on the
# 256 first tuning foods' slides (precise probe, three slides, three 1 % noise draws each,
# 768 readings, uncalibrated; median / 95th percentile / max of |mu error|, readings past
# 5 %): all samples 0.83 / 5.6 / 16.1 %, 47; share 0.1 0.81 / 3.2 / 8.3 %, 7; 0.15 0.82 /
# 3.0 / 6.3 %, 3; 0.2 0.84 / 3.0 / 6.3 %, 3; 0.3 0.92 / 3.0 / 6.0 %, 3; 0.5 0.88 / 3.3 /
# 7.5 %, 7.  With 0.3 % noise (two draws) 0.34 / 1.6 / 4.0 % went to 0.38 / 1.5 / 4.0 %,
# with 3 % 1.67 / 10.7 / 42.7 % to 1.77 / 7.6 / 12.8 %.  On all 512 tuning foods (one draw,
# benchmarks/slip_probe.py) 0.77 / 2.8 / 4.1 / 19 % (90th percentile before the max; foods
# past 1.4 %: 136) went to 0.87 / 2.7 / 3.1 / 6 % (154), and the mean error from -0.3 to
# -1.1 %: the weak samples' upward noise had hidden a low bias, the sticking samples just
# below mu that the slipping level cannot tell from slipping ones within the noise.  Without
# noise nothing is dropped.
NOISY_SLIP_MIN_SHARE = 0.2

# The slip probe is sampled at every physics step (run_probes; at 5 ms, 200 Hz gave
# estimate_friction the 20 samples of a 0.15 s slide; at 100 Hz only the envelope could be
# used).  Seeds 5000-5191, |mu error| median / 75th / 95th percentile / max, 5 ms step: 0.3 s
# slide at 100 Hz 0.2 / 1.3 / 6.6 / 28 %; 0.2 s, 100 Hz 0.2 / 1.4 / 5.6 / 48 %; 0.15 s,
# 100 Hz 0.2 / 1.3 / 7.2 / 34 %; 0.15 s, 200 Hz 0.1 / 1.0 / 4.9 / 24 %; at the
# 10 ms step, every step (100 Hz): 0.1 / 1.2 / 4.6 / 13 %.

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


# ProbeConfig's settings: name -> (low, high, low end excluded)
_PROBE_LIMITS: dict[str, tuple[float, float, bool]] = {
    "strain": (0.0, 0.5, True), "omega": (1e-3, 2.0, False), "hold": (0.0, 600.0, False),
    "settle": (0.05, 5.0, False), "slip_strain": (0.0, 0.5, True),
    "slip_omega": (1e-3, 2.0, False), "slip_hold": (0.0, 600.0, False),
    "slide_distance": (0.0, 0.02, True), "slide_time": (0.0, 120.0, True),
    "hold_time_scale": (1.0, 50.0, False), "hold_time_growth": (0.0, 0.5, False),
    "relaxation_impratio": (1.0, 1e4, False), "slip_timestep": (1e-4, 0.02, False),
}


@dataclass
class ProbeOutcome:
    """What the probes measured: estimates (NaN where not identified) and diagnostics."""

    estimates: dict[str, float]
    visco_valid: bool
    friction_valid: bool
    wall_time: float
    piece_index: int
    warnings: list[str] = field(default_factory=list)
    traces: dict[str, dict[str, np.ndarray]] = field(default_factory=dict)
    details: dict[str, Any] = field(default_factory=dict)
    intervals: dict[str, tuple[float, float]] = field(default_factory=dict)

    @property
    def reliable(self) -> bool:
        """Both probes gave estimates, the 95 % intervals of g1, tau1 and mu are each
        within ``RELIABLE_HALF_WIDTH`` of the estimate, or the widths the calibration's
        error model was fitted with (``details["reliable_half_width"]``,
        :func:`apply_calibration`; with an error model the intervals include the per-food
        error it predicts), and the diagnostics that model limits
        (``details["reliable_diagnostics"]``, e.g. the repeated clamps' spread) are within
        their limits."""
        if not (self.visco_valid and self.friction_valid):
            return False
        widths = self.details.get("reliable_half_width") or {}
        for name in ("g1", "tau1", "mu"):
            lo, hi = self.intervals.get(name, (math.nan, math.nan))
            v = self.estimates[name]
            if not (math.isfinite(lo) and math.isfinite(hi) and v > 0):
                return False
            if max(hi / v - 1.0, 1.0 - lo / v) > widths.get(name, RELIABLE_HALF_WIDTH):
                return False
        return not self.diagnostics_past_limits()

    def diagnostics_past_limits(self) -> list[str]:
        """The diagnostics past the limits of ``details["reliable_diagnostics"]``, as
        ``name=value``, or ``name missing`` where the probes gave none (which counts as
        past, as does a value that is not a finite number)."""
        values = self.details.get("diagnostics") or {}
        past = []
        for name, limit in (self.details.get("reliable_diagnostics") or {}).items():
            if name not in values:
                past.append(f"{name} missing")
                continue
            try:
                v = float(values[name])
            except (TypeError, ValueError):
                v = math.nan
            if not abs(v) <= limit:
                past.append(f"{name}={v:.3g}")
        return past


def probe_piece_index(pieces: tuple[Piece, ...]) -> int:
    """The piece nearest the layout's centre (ties: the lowest index)."""
    require_pieces("pieces", pieces)
    xy = np.array([[p.x, p.y] for p in pieces])
    centre = (xy.min(axis=0) + xy.max(axis=0)) / 2
    return int(np.argmin(np.linalg.norm(xy - centre, axis=1)))


def nominal_stiffness(piece: Piece) -> float:
    """Nominal instantaneous SLS stiffness K1 + K2 of a piece between the two faces [N/m].

    The study's equations give each half-spoon a displacement ``dx`` and the force ``F_n``
    on it; both faces squeeze the piece, so its compression is ``2 dx`` and
    ``F_n = (E A / l) 2 dx``: ``K = 2 E A / l`` with ``l`` the piece's width along the clamp
    and ``A`` its mid cross-section (the full face for a cube, the ellipse ``pi/4 w h``
    otherwise).  This ignores Poisson confinement and contact curvature, so it is a nominal
    scale, not what a perfect estimator must return: compare g_1, tau_1 and mu exactly and
    K1, K2, B as ratios.
    """
    require_type("piece", piece, Piece, "a Piece")
    ex, ey, ez = piece.extents
    area = ex * ez if piece.shape == "cube" else math.pi / 4 * ex * ez
    return 2.0 * piece.material.young * area / ey


def true_parameters(piece: Piece) -> dict[str, float]:
    """The oracle's values for a piece: K1, K2, B (nominal) and the material's mu, g1, tau1."""
    require_type("piece", piece, Piece, "a Piece")
    m = piece.material
    k = nominal_stiffness(piece)
    k2 = m.g1 * k
    return {"K1": k - k2, "K2": k2, "B": m.tau1 * k2, "mu": m.mu, "g1": m.g1, "tau1": m.tau1}


# Where the elastic twin is placed along the blade (x) for the true stiffness: at the
# centre, and where a chaotic contact event pushed it through a blade or the plate there (1
# of 256 reporting foods: a 20 mm, 0.23 MPa cube whose twin's held moment came out 800 times
# the food's, with a log strain of 11) or set it rattling between the blades (1 of 256: a
# 10 mm ellipsoid, :func:`_twin_fault`), a micrometre or two off, far below anything
# physical (a 1 um move of the same twins held them at 0.196 N m against 0.171 for the
# first food itself, and at 0.0339 N m against the second's peak of 0.0333).
TWIN_SHIFTS: tuple[float, ...] = (0.0, 1e-6, 2e-6, 3e-6)


def elastic_stiffness(piece: Piece, config: ProbeConfig,
                      geometry: Geometry | None = None) -> dict[str, float]:
    """The "true" instantaneous stiffness ``K1 + K2`` of a piece under the relaxation probe.

    One definition, used by ``food-fetch estimate``, the validation harness and the tests:
    the study's eq. 7 stiffness of the piece's purely elastic twin (the same piece with
    ``g1 = 0``) clamped by the same probe to the same angle, with the first-contact angle
    ``theta_c`` the faces reach the piece's rest surface at (:func:`first_contact_angle`):
    ``K_el = M_el cos(theta_d) / (L^2 (sin theta_d - sin theta_c))``, ``M_el`` the twin's held
    moment and ``theta_d`` the angle it was held at (the probe's, or where a stiff piece
    stalled the motor short of it).  Then ``K2 = g1 K_el``, ``K1 = (1 - g1) K_el`` and
    ``B = tau1 K2``.  Unlike a nominal ``2 E A / l`` this is what an exact estimator must
    return for this piece, shape and clamp (Poisson confinement, contact curvature and the
    contact's own compliance included); g1, tau1 and mu are the material's.  A twin that
    passes through a blade or the plate, or rattles between the blades
    (:func:`_twin_fault`), is clamped again a micrometre along the blade
    (:data:`TWIN_SHIFTS`).

    Raises:
        SimulationDivergedError: the twin was not held at any placement.

    Returns:
        ``{"K_el", "theta_c", "theta_d", "M_el"}`` (N/m, rad, rad, N m).
    """
    _check_probe_args(piece, config, geometry)
    hold = 0.5
    faults = []
    for shift in TWIN_SHIFTS:
        twin = dataclasses.replace(piece, x=shift, y=0.0,
                                   material=dataclasses.replace(piece.material, g1=0.0))
        sim = FetchSimulator((twin,), geometry, impratio=config.relaxation_impratio,
                             timestep=config.relaxation_timestep,
                             relaxation_contact_ratio=config.relaxation_contact_ratio)
        theta_c = first_contact_angle(sim.scene_for("relaxation"))[0]
        command = probe_angle(sim, config.strain, "relaxation")
        res = sim.run("relaxation", FetchAction(theta_d=command, omega=config.omega,
                                                hold=hold, settle=config.settle))
        late = res.traces["t"] > res.traces["t"][-1] - 0.5 * hold
        fault = _twin_fault(res, late)
        if fault is None:
            break
        faults.append(f"{1e6 * shift:g} um: {fault}")
    else:
        raise SimulationDivergedError(
            f"the elastic twin of this {piece.shape} was not held at any placement tried "
            f"along the blade ({'; '.join(faults)}): its true stiffness is undefined",
            res.scene, res.action.to_dict())
    tr = res.traces
    # The angle the twin was held at: the probe's, or where a stiff piece stalled the motor
    # short of it (the command it stalled on, as the estimators take theta_d).
    theta_d = float(tr["theta_cmd"][-1])
    m_el = float(np.mean(_mean_moment(tr)[late]))
    lever = float(res.geometry["L"])
    unit = lever**2 * (math.sin(theta_d) - math.sin(theta_c)) / math.cos(theta_d)
    return {"K_el": m_el / unit, "theta_c": theta_c, "theta_d": theta_d, "M_el": m_el}


# The most of the twin's late held samples on which one half-spoon may let go of it (its
# moment under a tenth of the other's) for the twin to count as held.
TWIN_MAX_LOST_SHARE = 0.1


def _twin_fault(res: SimResult, late: np.ndarray) -> str | None:
    """Why the elastic twin's clamp ``res`` does not define a stiffness, or None: it passed
    through a blade or the plate, or it rattles between the blades, one face letting go of
    it on more than ``TWIN_MAX_LOST_SHARE`` of the late hold's samples.

    Why the rattle: a purely elastic piece has none of the material's viscous damping, and
    a small, stiff round one can bounce between the faces for the whole hold while the
    food itself sits still (reporting food 179, a 10 mm, 0.42 MPa ellipsoid: its twin let
    go of the right face on every other sample, and their mean read K1 + K2 at 1.84 kN/m
    against 3.9-4.0 kN/m for the twin held a micrometre along the blade and 4.01 kN/m
    probed).  Of the 768 tuning and reporting twins, that one lost a face on more than one
    late sample; one soft cube's lost it on one sample of 25, while jiggling by +-5 %."""
    if res.pieces[0]["passed_through"]:
        return "it passed through a blade or the plate"
    left, right = res.traces["moment_left"][late], res.traces["moment_right"][late]
    lost = np.minimum(left, right) < 0.1 * np.maximum(left, right)
    if lost.mean() > TWIN_MAX_LOST_SHARE:
        return (f"it rattles between the blades, one face letting go of it on "
                f"{int(lost.sum())} of {lost.size} late held samples")
    return None


def true_parameters_exact(piece: Piece, config: ProbeConfig,
                          geometry: Geometry | None = None) -> dict[str, float]:
    """K1, K2, B from :func:`elastic_stiffness` and the material's mu, g1, tau1."""
    m = piece.material
    k_el = elastic_stiffness(piece, config, geometry)["K_el"]
    k2 = m.g1 * k_el
    return {"K1": k_el - k2, "K2": k2, "B": m.tau1 * k2, "mu": m.mu, "g1": m.g1, "tau1": m.tau1}


def first_contact_angle(scene: Scene) -> tuple[float, float, float]:
    """Where the blade faces first touch the piece, from its rest surface (a depth camera).

    Each face is at ``pose.face_y(theta, depth)`` from the hinge plane at ``depth`` below the
    axis; a surface vertex at lateral distance ``y`` and depth ``h`` is reached when
    ``face_offset / cos(theta) - h tan(theta) = y`` (solved by Newton's method for every
    vertex above the blade tip).

    Returns:
        (theta_contact [rad], depth of the first-touched vertex [m], the piece's half-width
        across the faces [m]).
    """
    require_type("scene", scene, Scene, "a Scene (build_scene)")
    d = initial_state(scene)
    pose = scene.pose
    v = np.asarray(d.flexvert_xpos)
    lateral = np.abs(v[:, 1] - pose.stage_xy[1])
    depth = pose.hinge_height - v[:, 2]
    reach = depth < scene.geometry.blade_length
    if not reach.any():
        return 0.0, pose.L, float(lateral.max())
    y, h = lateral[reach], depth[reach]
    th = np.zeros(y.size)
    for _ in range(8):
        f = pose.face_offset / np.cos(th) - h * np.tan(th) - y
        df = pose.face_offset * np.sin(th) / np.cos(th) ** 2 - h / np.cos(th) ** 2
        th = th - f / df
    k = int(np.argmin(th))
    return float(max(th[k], 0.0)), float(h[k]), float(lateral.max())


def probe_angle(sim: FetchSimulator, strain: float, experiment: str) -> float:
    """Clamp angle squeezing the piece by ``strain`` of its width past first contact.

    Small-angle travel of the contact point is ``depth * theta``; the result stays below
    the angle at which the faces would meet.
    """
    require_type("sim", sim, FetchSimulator, "a FetchSimulator")
    require_finite("strain", strain)
    require(0 < strain <= 1, "strain", strain, "in (0, 1]")
    scene = sim.scene_for(experiment)
    theta_c, depth, half_width = first_contact_angle(scene)
    theta = theta_c + strain * half_width / depth
    closed = getattr(scene.pose, "theta_closed", math.inf)
    return float(min(theta, 0.9 * closed))


def _mean_moment(tr: dict[str, np.ndarray]) -> np.ndarray:
    return 0.5 * (tr["moment_left"] + tr["moment_right"])


def _noisy(x: np.ndarray, noise: float, rng: np.random.Generator | None) -> np.ndarray:
    """``x`` plus white noise of sd ``noise`` times its peak (a sensor's noise floor)."""
    if noise <= 0 or rng is None:
        return x
    return x + noise * float(np.max(np.abs(x))) * rng.standard_normal(x.shape)


def estimate_viscoelastic(result: SimResult, noise: float = 0.0,
                          rng: np.random.Generator | None = None,
                          diagnostics: dict[str, float] | None = None,
                          drift_diagnostics: bool = True,
                          theta_contact: float | None = None
                          ) -> tuple[dict[str, float], list[str], dict[str, tuple[float, float]]]:
    """K1, K2, B, g1, tau1 from a relaxation run, with 95 % intervals: from the hold past
    ``HOLD_SETTLE``, with the contact angle of the full fit (else the three-step method),
    whose values stand in where the hold gives none (their intervals then NaN).

    ``noise`` (with ``rng``) adds white noise of that share of the peak to the moment first.
    ``diagnostics``, where given, receives the fit's diagnostics (:func:`_from_the_hold`),
    with :func:`estimators.uncertainty.drift_diagnostics` where ``drift_diagnostics``.
    ``theta_contact`` [rad], where given, is the first-contact angle the hold fit uses
    instead of the full fit's (``ProbeConfig.contact_angle``, :func:`first_contact_angle`).

    Raises :class:`EstimationError` when neither method can use the trace.
    """
    _check_run_args(result, "relaxation", noise, rng)
    if theta_contact is not None:
        require_finite("theta_contact", theta_contact)
        require(theta_contact >= 0.0, "theta_contact", theta_contact, ">= 0 rad")
    vals, warns, intervals, _ = _estimate_clamp(result, noise, rng, diagnostics,
                                                drift_diagnostics, theta_contact)
    return vals, warns, intervals


def _clamp_samples(result: SimResult, noise: float, rng: np.random.Generator | None
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray, ClampGeometry, float]:
    """The clamp and hold samples a relaxation run's fit reads: (t from the clamp start,
    the commanded angle, the moment with ``noise``, the clamp geometry, theta_d)."""
    tr = result.traces
    t0 = float(result.extra.get("t_clamp_start", 0.0))
    # The hold angle the motor was told (the run ends in the hold): theta_d, or where a stiff
    # piece stalled it, which can be a little below the command it stalled on (the angle the
    # blades had reached, not the largest command).
    theta_d = float(tr["theta_cmd"][-1])
    t_d = t0 + theta_d / result.action.omega
    sel = (tr["t"] >= t0) & np.isin(tr["phase"], [PHASE_CODE["clamp"], PHASE_CODE["hold"]])
    # The first HOLD_SKIP of the hold is the servo and the contact catching up with the
    # command (the moment still rises for ~50 ms); eq. 6 holds after it, so leave it out.
    sel &= ~((tr["t"] > t_d + 1e-9) & (tr["t"] < t_d + HOLD_SKIP - 1e-9))
    geom = ClampGeometry(L=float(result.geometry["L"]), theta_0=float(result.geometry["theta_0"]))
    # The commanded angle, not the measured one: the servo sags by ~1e-5 rad under load, more
    # than the estimators' plateau tolerance (the hold is then not found on spheres), and a
    # position-controlled motor knows its command.
    t, moment = tr["t"][sel] - t0, _noisy(_mean_moment(tr)[sel], noise, rng)
    return t, tr["theta_cmd"][sel], moment, geom, theta_d


def _estimate_clamp(result: SimResult, noise: float, rng: np.random.Generator | None,
                    diagnostics: dict[str, float] | None, drift_diagnostics: bool,
                    theta_contact: float | None = None
                    ) -> tuple[dict[str, float], list[str], dict[str, tuple[float, float]],
                               ViscoelasticEstimate]:
    """:func:`estimate_viscoelastic`, with the full (or three-step) fit whose contact angle
    (or ``theta_contact``, where given and below the hold angle) and clamp timing the hold
    fit used."""
    t, theta_cmd, moment, geom, theta_d = _clamp_samples(result, noise, rng)
    args = (t, theta_cmd, moment, geom)
    kw = {"omega": result.action.omega, "theta_d": theta_d}
    errors: list[str] = []
    for method, extra in ((estimate_full_fit, {"clamp_weight": CLAMP_WEIGHT}),
                          (estimate_three_step, {})):
        try:
            est = method(*args, **kw, **extra)
        except (EstimationError, ArithmeticError, np.linalg.LinAlgError) as exc:
            # ArithmeticError: estimate_full_fit can overflow in math.exp on wild fits.
            errors.append(f"{method.__name__}: {type(exc).__name__}: {exc}")
            continue
        if all(np.isfinite(v) and v > 0 for v in _visco_values(est).values()):
            est, angle_warnings = _with_contact_angle(est, theta_contact)
            vals, warns, intervals = _from_the_hold(est, t, moment, geom, diagnostics,
                                                    drift_diagnostics)
            return vals, [*errors, *angle_warnings, *warns], intervals, est
        errors.append(f"{method.__name__}: not identified ({'; '.join(est.warnings)})")
    raise EstimationError("; ".join(errors))


def _with_contact_angle(est: ViscoelasticEstimate, theta_contact: float | None
                        ) -> tuple[ViscoelasticEstimate, list[str]]:
    """``est`` with its contact angle replaced by ``theta_contact`` where that is given and
    leaves a squeeze (below the hold angle: a motor that stalled short of the camera's
    contact angle touched the piece earlier, and the fit's angle says where; a warning
    says so)."""
    if theta_contact is None:
        return est, []
    if not theta_contact < est.theta_d:
        return est, [f"the camera's contact angle {theta_contact:.6g} rad is not below the "
                     f"hold angle {est.theta_d:.6g} rad: K1, K2 and B are at the fit's "
                     f"contact angle {est.theta_1:.6g} rad"]
    return dataclasses.replace(est, theta_1=float(theta_contact)), []


def _from_the_hold(est: ViscoelasticEstimate, t: np.ndarray, moment: np.ndarray,
                   geom: ClampGeometry, diagnostics: dict[str, float] | None = None,
                   drift_diagnostics: bool = True
                   ) -> tuple[dict[str, float], list[str], dict[str, tuple[float, float]]]:
    """K1, K2, B, g1, tau1 from the hold alone (:func:`estimators.estimate_from_hold`, past
    ``HOLD_SETTLE``) with their 95 % intervals (:func:`estimators.uncertainty.
    hold_with_intervals`), with the contact angle and t_d of the full fit ``est``; the fit's
    own values and warnings, plus a warning, where the hold gives none.

    Why: the full fit weights the clamp, whose rise is not the SLS's where a piece rocks or
    chatters as the blades close, and it then misplaces M(t_d), g1 and tau1; the hold past
    ``HOLD_SETTLE`` follows eq. 6 for any SLS held at a constant angle.

    ``diagnostics`` (where given) receives the hold's (:func:`estimators.uncertainty.
    hold_diagnostics`), the noise and window-shift log-sds of g1 and tau1 (``sd_noise_g1``,
    ...) and the clamp fit's R^2: the inputs of the calibration's error model.
    """
    try:
        hwi = hold_with_intervals(t, moment, geom, est.theta_1, est.theta_d, est.omega, est.t_d,
                                  settle=HOLD_SETTLE, systematic={
                                      k: v for k, v in PROBE_SYSTEMATIC_SD.items() if k != "mu"},
                                  with_drift_diagnostics=drift_diagnostics)
        hold = hwi.estimate
    except (EstimationError, ArithmeticError) as exc:
        hold, why = None, str(exc)
    else:
        why = f"it gives g1={hold.g1!r}, tau1={hold.tau1!r}"
        if diagnostics is not None:
            diagnostics.update(hwi.diagnostics, r2_clamp=float(est.r2_clamp))
            for k in ("g1", "tau1"):
                diagnostics[f"sd_noise_{k}"] = hwi.sd_noise[k]
                diagnostics[f"sd_model_{k}"] = hwi.sd_model[k]
    if hold is None or not (0.0 < hold.g1 < 1.0 and 0.0 < hold.tau1 < math.inf):
        nan = (math.nan, math.nan)
        return (_visco_values(est),
                [*est.warnings, f"the parameters are the fit's, not the hold's: {why}"],
                dict.fromkeys(VISCO_NAMES, nan))
    return _visco_values(hold), [], dict(hwi.intervals)


def _visco_values(est: ViscoelasticEstimate | HoldEstimate) -> dict[str, float]:
    """K1, K2, B, g1, tau1 of an estimate, by name."""
    return {name: float(getattr(est, name)) for name in VISCO_NAMES}


def estimate_mu(result: SimResult, noise: float = 0.0, rng: np.random.Generator | None = None,
                diagnostics: dict[str, float] | None = None,
                envelope: SlipEnvelope = "sum"
                ) -> tuple[float, list[str], tuple[float, float]]:
    """mu from a slip run, with a 95 % interval; raises :class:`EstimationError` when the
    trace cannot give it.

    Coulomb friction bounds the force ratio |F_t| / F_n by mu, and reaches it only while the
    blades slide.  A soft or round piece stick-slips under the blades (the ratio swings
    between ~0.05 and mu), and ``estimate_friction`` may then return a sticking plateau below
    mu; so mu is the larger of its estimate and the upper envelope of the ratio (its
    ``ENVELOPE_QUANTILE`` quantile over the last three quarters of the slide, where the
    blades grip; with ``envelope="per_blade"`` each half-spoon's, the lower of the two, and
    the lower of the two faces' plateaus; with ``"per_blade_denoised"`` (or
    ``"per_blade_slipping"``, refined to the slipping level, or ``"per_blade_simex"``, that
    level less the bias the noise leaves in it, :mod:`fetch_env.slip_simex`) those
    envelopes less what sensor noise adds, see :data:`SLIP_ENVELOPES`).  The interval adds,
    on the log scale, the estimator's own (noise) interval and what noise added to the
    envelope, the
    gap between the plateau and the envelope and between the two half-spoons (model error),
    and ``PROBE_SYSTEMATIC_SD['mu']``.  ``noise`` (with ``rng``) adds white noise of that
    share of each force trace's peak first.  ``diagnostics`` (where
    given) receives the slide's (:func:`_mu_diagnostics`).
    """
    _check_run_args(result, "slip", noise, rng)
    require(isinstance(envelope, str) and envelope in SLIP_ENVELOPES, "envelope", envelope,
            f"one of {SLIP_ENVELOPES}")
    tr = result.traces
    slide = tr["phase"] == PHASE_CODE["slide"]
    if not slide.any():
        raise EstimationError("the slip run has no slide phase")
    keys = ("normal_left", "tangential_left", "normal_right", "tangential_right")
    f = {k: _noisy(tr[k], noise, rng) for k in keys}
    idx = np.flatnonzero(slide)
    late = idx[len(idx) // 4:]
    normal = f["normal_left"][late] + f["normal_right"][late]
    tang = f["tangential_left"][late] + f["tangential_right"][late]
    grip = normal > 0.05 * max(float(normal.max()), 1e-12)
    if grip.sum() < 5:
        raise EstimationError("no steady grip during the slide (the blades lost the piece)")
    ratio = np.abs(tang[grip]) / normal[grip]
    warns: list[str] = []
    by_blade = envelope != "sum"
    noise_sd = None
    if envelope in ("per_blade_denoised", "per_blade_slipping", "per_blade_simex"):
        noise_sd = _settle_noise(tr["phase"], f)
        if noise_sd is None:
            warns.append("fewer than 5 samples before the blades touch: the envelope is not "
                         "corrected for sensor noise")
    slipping = envelope in ("per_blade_slipping", "per_blade_simex")
    per_blade = (_per_blade_envelope(f, late, grip, noise_sd, slipping=slipping)
                 if by_blade else None)
    if envelope == "per_blade_simex" and per_blade is not None and noise_sd is not None \
            and max(noise_sd.values()) > 0:
        # the noise share (per_blade[1], for mu's interval) stays the uncorrected level's:
        # the error model fitted on such readings sizes what the extrapolation leaves
        per_blade, why = _extrapolated(f, late, keys, noise_sd, per_blade)
        if why:
            warns.append(f"the slipping level's noise bias was not extrapolated ({why}): mu "
                         "read without the correction")
    if by_blade and per_blade is None:
        warns.append("fewer than 5 samples where both half-spoons grip: mu from the summed "
                     "forces' envelope")
    env, noise_share = ((float(np.quantile(ratio, ENVELOPE_QUANTILE)), 0.0)
                        if per_blade is None else per_blade)
    est = None
    try:
        est = estimate_friction(tr["t"], *(f[k] for k in keys),
                                slide_start=float(tr["t"][slide][0]))
        plateau = float(est.mu)
        if by_blade and est.mu_left > 0 and est.mu_right > 0:
            plateau = min(float(est.mu_left), float(est.mu_right))
        warns += list(est.warnings)
    except (EstimationError, ArithmeticError) as exc:
        # Its plateau test is strict for a short slide (the ratio drifts by ~1 % as the
        # normal force relaxes).
        plateau = math.nan
        warns.append(f"estimate_friction: {exc}; mu from the ratio's envelope")
    # Read at the slipping level (noise present), the envelope is already the level a
    # steady slide sits at, from the same samples as the plateau, so the plateau is no
    # second reading (on the 256 tuning foods with 1 % noise letting it override moved mu's
    # median |error| by 0.01 points and its 95th percentile not at all; on a synthetic,
    # perfectly steady slide the plateau is the steadier, sd 0.23 % against 0.29 %,
    # tests/test_slip_envelope.py).
    level_read = (slipping and per_blade is not None
                  and noise_sd is not None and max(noise_sd.values()) > 0)
    if np.isfinite(plateau) and plateau >= env and not level_read:
        mu = plateau
    else:
        mu = env
        if np.isfinite(plateau) and plateau < 0.98 * env:
            warns.append(f"estimate_friction's plateau {plateau:.3g} is below the ratio's "
                         f"envelope {env:.3g} (stick-slip): mu from the envelope")
    if not (np.isfinite(mu) and mu > 0):
        raise EstimationError(f"friction estimate is not finite and positive: {mu!r}")
    sd = math.hypot(_mu_sd_log(mu, est, env, noise_share), PROBE_SYSTEMATIC_SD["mu"])
    if diagnostics is not None:
        diagnostics.update(_mu_diagnostics(mu, est, env, ratio, float(grip.mean()),
                                           noise_share))
    return mu, warns, log_interval(mu, sd)


def _extrapolated(f: dict[str, np.ndarray], late: np.ndarray, keys: tuple[str, ...],
                  noise_sd: dict[str, float], per_blade: tuple[float, float]
                  ) -> tuple[tuple[float, float], str]:
    """``per_blade`` with its slipping level freed of the noise's bias by SIMEX
    (:func:`fetch_env.slip_simex.simex_level`), and "" ; or ``per_blade`` as it was and why
    not (forces that are not finite, copies of the slide that lost their grip, a level
    extrapolated to zero or below)."""
    if not all(np.isfinite(f[k][late]).all() for k in keys):
        return per_blade, "the late slide's forces are not all finite"
    level = simex_level({k: f[k][late] for k in keys}, noise_sd, per_blade[0], _level_rule(),
                        SLIP_SIMEX)
    if level is None:
        return per_blade, "noisier copies of the slide lost their grip"
    if not level > 0:
        return per_blade, f"it extrapolated to {level:.3g}"
    return (level, per_blade[1]), ""


def _per_blade_envelope(f: dict[str, np.ndarray], late: np.ndarray, grip: np.ndarray,
                        noise_sd: dict[str, float] | None = None, slipping: bool = False
                        ) -> tuple[float, float] | None:
    """The lower of the two half-spoons' ``ENVELOPE_QUANTILE`` envelopes of their own force
    ratio, over the late slide's samples where both grip (each above 5 % of its own peak),
    and the share of it that noise took off (0 without ``noise_sd``); None where fewer than
    5 such samples exist.  With ``noise_sd`` (each force trace's noise sd,
    :func:`_settle_noise`, some of it positive) only the firmly pressed samples are read
    (:func:`_firmly_pressed`) and each envelope is less ``NOISE_QUANTILE_Z`` times the median noise
    sd of its ratio (see :data:`SLIP_ENVELOPES`), and, with ``slipping``, refined to the
    ratio's slipping level (:func:`_slipping_level`); the larger of the two half-spoons'
    shares taken off is returned: a log-sd of mu's noise, for its interval."""
    both = grip.copy()
    sides = []
    for side in ("left", "right"):
        n, t = f[f"normal_{side}"][late], f[f"tangential_{side}"][late]
        both &= n > 0.05 * max(float(n.max()), 1e-12)
        sides.append((side, n, np.abs(t)))
    if both.sum() < 5:
        return None
    if noise_sd is not None and max(noise_sd.values()) > 0:
        both = _firmly_pressed(sides, both)
    envelopes, shares = [], [0.0]
    for side, n, t in sides:
        ratio = t[both] / n[both]
        env = float(np.quantile(ratio, ENVELOPE_QUANTILE))
        if noise_sd is not None:
            sd_ratio = np.hypot(noise_sd[f"tangential_{side}"],
                                ratio * noise_sd[f"normal_{side}"]) / n[both]
            s = float(np.median(sd_ratio))
            taken = NOISE_QUANTILE_Z * s
            if slipping and s > 0:
                taken = env - _slipping_level(ratio, env - taken, s)
            shares.append(taken / env if env > 0 else 0.0)
            env -= taken
        envelopes.append(env)
    return min(envelopes), max(shares)


def _firmly_pressed(sides: list[tuple[str, np.ndarray, np.ndarray]], both: np.ndarray
                    ) -> np.ndarray:
    """The samples of ``both`` where each half-spoon's normal force is at least
    :data:`NOISY_SLIP_MIN_SHARE` of its largest over ``both`` (where their ratios' noise is
    at most ~1 / share times the least); ``both`` itself where fewer than 5 are."""
    firm = both.copy()
    for _, n, _ in sides:
        firm &= n >= NOISY_SLIP_MIN_SHARE * float(n[both].max())
    return firm if firm.sum() >= 5 else both


def _slipping_level(ratio: np.ndarray, start: float, sd: float) -> float:
    """The level a force ratio sits at while its face slips, from its samples with noise
    of sd ``sd``: from ``start``, ``SLIPPING_ITERATIONS`` times the mean of the samples
    above the level less ``SLIPPING_TAIL`` sds, less the shift that cut puts into a
    normal's mean (``sd phi(c) / Phi(c)``); where fewer than 3 samples are that high, the
    level so far (see :data:`SLIP_ENVELOPES`)."""
    c = SLIPPING_TAIL
    shift = float(slipping_shift(sd, c))
    level = start
    for _ in range(SLIPPING_ITERATIONS):
        top = ratio[ratio > level - c * sd]
        if top.size < 3:
            break
        level = float(top.mean()) - shift
    return level


def _level_rule() -> LevelRule:
    """The slipping level's constants, as :mod:`fetch_env.slip_simex` reads many copies."""
    return LevelRule(quantile=ENVELOPE_QUANTILE, noise_z=NOISE_QUANTILE_Z, tail=SLIPPING_TAIL,
                     iterations=SLIPPING_ITERATIONS, min_share=NOISY_SLIP_MIN_SHARE)


def _settle_noise(phase: np.ndarray, f: dict[str, np.ndarray]) -> dict[str, float] | None:
    """Each force trace's sd over the settle phase, before the blades touch the food (its
    true forces are zero there, so what it reads is the sensor's noise); None where fewer
    than 5 settle samples exist."""
    settle = phase == PHASE_CODE["settle"]
    if settle.sum() < 5:
        return None
    return {k: float(np.std(v[settle])) for k, v in f.items()}


def _mu_diagnostics(mu: float, est: Any, envelope: float, ratio: np.ndarray, grip: float,
                    noise_share: float = 0.0) -> dict[str, float]:
    """How steady the slide was, for the calibration's error model: whether
    estimate_friction found a plateau (``mu_plateau``), the log-gaps of its plateau to the
    envelope (``mu_gap``) and of the two half-spoons (``mu_lr``), its noise log-sd
    (``sd_noise_mu``, with the share of the envelope that sensor noise added, see
    :func:`_per_blade_envelope`), the spread of the force ratio below mu (``mu_spread``: its median
    over mu, logged; a stick-slipping piece sits far below) and the share of the late slide
    the blades gripped (``mu_grip``)."""
    noise, gap, lr = _mu_log_parts(mu, est, envelope, noise_share)
    return {"mu_plateau": float(est is not None), "mu_gap": gap,
            "mu_lr": lr, "sd_noise_mu": noise,
            "mu_spread": math.log(max(float(np.median(ratio)) / mu, 1e-6)), "mu_grip": grip}


def _mu_log_parts(mu: float, est: Any, envelope: float, noise_share: float = 0.0
                  ) -> tuple[float, float, float]:
    """On the log scale: the noise sd (the friction estimator's, and ``noise_share``, what
    sensor noise added to the envelope), the gap of mu to the force ratio's envelope and
    half the gap between the two half-spoons (0 where not defined)."""
    noise = lr = 0.0
    if est is not None:
        lo, hi = est.interval
        noise = (math.log(hi / lo) / (2 * 1.96)) if lo > 0 and hi > lo else 0.0
    noise = math.hypot(noise, noise_share)
    if est is not None and est.mu_left > 0 and est.mu_right > 0:
        lr = 0.5 * abs(math.log(est.mu_left / est.mu_right))
    gap = abs(math.log(envelope / mu)) if envelope > 0 else 0.0
    return noise, gap, lr


def _mu_sd_log(mu: float, est: Any, envelope: float, noise_share: float = 0.0) -> float:
    """Log-sd of mu: the noise (the friction estimator's interval, what sensor noise added
    to the envelope), and the disagreement of the plateau with the envelope and of the two
    half-spoons (see :func:`estimate_mu`)."""
    if est is None:  # the envelope alone: no check of it
        return math.hypot(abs(math.log(envelope / mu)) + 0.05, noise_share)
    return float(np.sqrt(np.sum(np.square(_mu_log_parts(mu, est, envelope, noise_share)))))


def repeat_strains(config: ProbeConfig) -> list[float]:
    """The squeezes of the relaxation clamps: ``strain`` first, then alternately below and
    above it by ``repeat_strain_step`` of it, ``strain * (1, 1 - s, 1 + s, 1 - 2 s, ...)``."""
    return [config.strain * (1.0 - m * config.repeat_strain_step)
            for m in _alternating_steps(config.relaxation_repeats)]


def _alternating_steps(n: int) -> list[int]:
    """``n`` signed step counts of repeats around a first setting: 0, 1, -1, 2, -2, ..."""
    return [(j + 1) // 2 * (1 if j % 2 else -1) for j in range(n)]


def _relaxation_simulator(piece: Piece, config: ProbeConfig,
                          geometry: Geometry | None) -> FetchSimulator:
    """The simulator of ``piece`` alone under ``config``'s relaxation settings."""
    return FetchSimulator((piece,), geometry, impratio=config.relaxation_impratio,
                          timestep=config.relaxation_timestep,
                          relaxation_contact_ratio=config.relaxation_contact_ratio)


def _relaxation_clamp(sim: FetchSimulator, config: ProbeConfig, strain: float) -> SimResult:
    """One relaxation clamp of ``sim``'s piece, squeezed by ``strain`` past first contact,
    its hold time-scaled past ``HOLD_SETTLE``."""
    theta_d = probe_angle(sim, strain, "relaxation")
    action = FetchAction(theta_d=theta_d, omega=config.omega, hold=config.hold,
                         settle=config.settle)
    return sim.run("relaxation", action,
                   time_scale=TimeScale(config.hold_time_scale, realtime=HOLD_SETTLE,
                                        growth=config.hold_time_growth))


def relaxation_run(piece: Piece, config: ProbeConfig, geometry: Geometry | None,
                   strain: float) -> SimResult:
    """One relaxation clamp of ``piece`` at ``strain`` in a simulator of its own (a probe
    worker's task, :func:`run_probes`'s ``workers``)."""
    return _relaxation_clamp(_relaxation_simulator(piece, config, geometry), config, strain)


def _relaxation_probe(piece: Piece, config: ProbeConfig, geometry: Geometry | None,
                      noise: float, rng: np.random.Generator, out: ProbeOutcome,
                      keep_traces: bool, drift_diagnostics: bool = True,
                      ahead: list[Any] | None = None) -> None:
    """Run the relaxation probe on ``piece`` (``config.relaxation_repeats`` clamps) and put
    its estimates into ``out`` (with the hold's drift diagnostics where
    ``drift_diagnostics``); the first clamp's action, geometry and traces are kept.
    ``ahead``: the clamps already run (:func:`fetch_env.parallel.run_ahead`), in order."""
    sim = _relaxation_simulator(piece, config, geometry)
    runs = ([_relaxation_clamp(sim, config, strain) for strain in repeat_strains(config)]
            if ahead is None else [outcome(r) for r in ahead])
    out.details["relaxation_action"] = runs[0].action.to_dict()
    out.details["relaxation_geometry"] = runs[0].geometry  # L and theta_0 for the SLS
    out.details["relaxation_max_log_strain"] = max(
        float(r.traces["max_log_strain"].max()) for r in runs)
    if keep_traces:
        out.traces["relaxation"] = runs[0].traces
    theta_contact = (first_contact_angle(sim.scene_for("relaxation"))[0]
                     if config.contact_angle == "camera" else None)
    fit_start, cpu_start = time.perf_counter(), time.process_time()
    fits, failures = _fit_clamps(runs, noise, rng, drift_diagnostics, theta_contact)
    out.details["wall_fits"] = out.details.get("wall_fits", 0.0) + time.perf_counter() - fit_start
    _add_cpu(out, "cpu_fits", cpu_start)
    if not fits:
        raise EstimationError(failures[0])
    fit = _median_of_clamps(fits)
    out.details.setdefault("diagnostics", {}).update(fit.diagnostics)
    out.estimates.update(fit.values)
    out.intervals.update(fit.intervals)
    out.warnings += fit.warnings
    if failures:
        out.warnings.append(f"{len(failures)} of {len(runs)} relaxation clamps gave no "
                            f"estimate: {failures[0]}")
    out.visco_valid = True


def _fit_clamps(runs: list[SimResult], noise: float, rng: np.random.Generator,
                drift_diagnostics: bool, theta_contact: float | None = None
                ) -> tuple[list[_ClampFit], list[str]]:
    """Each clamp's estimates, and why the others gave none.  The first clamp that can be
    fitted gets the full fit, intervals and diagnostics (:func:`estimate_viscoelastic`);
    the others only the hold fit, with its contact angle and clamp start (the piece and
    the blades' start are the same; the hold fit is a fifth of the full fit's time)."""
    fits: list[_ClampFit] = []
    failures: list[str] = []
    first: ViscoelasticEstimate | None = None
    for res in runs:
        try:
            if first is None:
                diagnostics: dict[str, float] = {}
                vals, warns, intervals, first = _estimate_clamp(res, noise, rng, diagnostics,
                                                                drift_diagnostics,
                                                                theta_contact)
                fits.append(_ClampFit(vals, warns, intervals, diagnostics))
            else:
                vals, drift = _hold_values(res, first, noise, rng, drift_diagnostics)
                fits.append(_ClampFit(vals, [], {}, drift))
        except (EstimationError, ArithmeticError) as exc:
            failures.append(str(exc))
    return fits, failures


def _hold_values(result: SimResult, first: ViscoelasticEstimate, noise: float,
                 rng: np.random.Generator, drift_diagnostics: bool
                 ) -> tuple[dict[str, float], dict[str, float]]:
    """K1, K2, B, g1, tau1 of a repeated clamp from its hold alone
    (:func:`estimators.estimate_from_hold` past ``HOLD_SETTLE``), with the contact angle and
    clamp start of the first clamp's fit ``first``; and, where ``drift_diagnostics``, its
    hold's :func:`estimators.uncertainty.drift_diagnostics` (else an empty dict)."""
    t, _, moment, geom, theta_d = _clamp_samples(result, noise, rng)
    omega = result.action.omega
    t_d = first.t_d - first.theta_d / first.omega + theta_d / omega
    args = (t, moment, geom, first.theta_1, theta_d, omega, t_d)
    hold = estimate_from_hold(*args, settle=HOLD_SETTLE)
    vals = _visco_values(hold)
    if not (0.0 < vals["g1"] < 1.0 and 0.0 < vals["tau1"] < math.inf):
        raise EstimationError(f"the hold gives g1={vals['g1']!r}, tau1={vals['tau1']!r}")
    drift = (uncertainty_drift(*args, settle=HOLD_SETTLE, plain=hold) if drift_diagnostics
             else {})
    return vals, drift


@dataclass
class _ClampFit:
    """The estimates of one relaxation clamp (or the median of several)."""

    values: dict[str, float]
    warnings: list[str]
    intervals: dict[str, tuple[float, float]]
    diagnostics: dict[str, float]


def _median_of_clamps(fits: list[_ClampFit]) -> _ClampFit:
    """One estimate from several clamps' fits, the first a full one at the set squeeze: the
    medians of g1 and tau1 (on the log scale) and the first clamp's K1 + K2 (a piece's
    stiffness moves with the squeeze, and the truth is the set squeeze's), from which K1, K2
    and B follow as one SLS; the first fit's intervals, moved with the values, and its
    diagnostics, but the drift pair (``DRIFT_DIAGNOSTICS``) the clamps' mean where every
    clamp has it, with the clamps' spread of log g1 and log tau1 (``repeat_sd_log_g1``,
    ``repeat_sd_log_tau1``)."""
    if len(fits) == 1:
        return fits[0]
    first = fits[0]
    logs = {k: np.log([f.values[k] for f in fits]) for k in ("g1", "tau1")}
    g1, tau1 = (float(np.exp(np.median(logs[k]))) for k in ("g1", "tau1"))
    sls = SLSParams.from_prony(first.values["K1"] + first.values["K2"], g1, tau1)
    values = {"K1": sls.K1, "K2": sls.K2, "B": sls.B, "g1": g1, "tau1": tau1}
    intervals = {}
    for name, v in values.items():
        lo, hi = first.intervals.get(name, (math.nan, math.nan))
        intervals[name] = (lo * v / first.values[name], hi * v / first.values[name])
    diagnostics = dict(first.diagnostics, repeat_sd_log_g1=float(np.std(logs["g1"], ddof=1)),
                       repeat_sd_log_tau1=float(np.std(logs["tau1"], ddof=1)))
    # the contact's creep, which the tau1 calibration reads, seen by every clamp
    for key in DRIFT_DIAGNOSTICS:
        if all(key in f.diagnostics for f in fits):
            diagnostics[key] = float(np.mean([f.diagnostics[key] for f in fits]))
    return _ClampFit(values, list(first.warnings), intervals, diagnostics)


def slip_run(piece: Piece, config: ProbeConfig, geometry: Geometry | None = None) -> SimResult:
    """The induced-slip probe's run on ``piece`` with ``config``'s slip settings: a clamp to
    ``slip_strain`` past first contact, a short hold and the slide, recorded at every physics
    step (and at least the simulator's 100 Hz); :func:`estimate_mu` reads it."""
    _check_probe_args(piece, config, geometry)
    if config.slip_gap is not None:
        geometry = dataclasses.replace(geometry or Geometry(), gap=config.slip_gap)
    sim = FetchSimulator((piece,), geometry, record_hz=max(100.0, 1.0 / config.slip_timestep),
                         timestep=config.slip_timestep)
    theta_d = probe_angle(sim, config.slip_strain, "slip")
    action = FetchAction(theta_d=theta_d, omega=config.slip_omega, hold=config.slip_hold,
                         settle=config.settle, slide_distance=config.slide_distance,
                         slide_time=config.slide_time)
    return sim.run("slip", action)


def slide_times(config: ProbeConfig) -> list[float]:
    """The durations of the slip probe's slides: ``slide_time`` first, then alternately
    slower and faster by :data:`SLIP_REPEAT_TIME_RATIO`, ``slide_time * (1, r, 1 / r, r^2,
    1 / r^2, ...)``."""
    return [config.slide_time * SLIP_REPEAT_TIME_RATIO ** m
            for m in _alternating_steps(config.slip_repeats)]


def _slide_run(piece: Piece, config: ProbeConfig, geometry: Geometry | None,
               slide_time: float) -> SimResult:
    """One slide of the slip probe, ``slide_time`` long (a probe worker's task too)."""
    return slip_run(piece, dataclasses.replace(config, slide_time=slide_time), geometry)


@dataclass
class _SlideFit:
    """mu from one slide of the slip probe."""

    mu: float
    warnings: list[str]
    interval: tuple[float, float]
    diagnostics: dict[str, float]


def _slip_probe(piece: Piece, config: ProbeConfig, geometry: Geometry | None, noise: float,
                rng: np.random.Generator, out: ProbeOutcome, keep_traces: bool,
                ahead: list[Any] | None = None) -> None:
    """Run the induced-slip probe on ``piece`` (``config.slip_repeats`` slides) and put its
    estimate of mu into ``out``; the first slide's action and traces are kept.  ``ahead``:
    the slides already run (:func:`fetch_env.parallel.run_ahead`), in order."""
    fits: list[_SlideFit] = []
    failures: list[str] = []
    for j, slide_time in enumerate(slide_times(config)):
        try:
            res = (_slide_run(piece, config, geometry, slide_time)
                   if ahead is None else outcome(ahead[j]))
        except SimulationDivergedError as exc:
            failures.append(str(exc))
            continue
        if j == 0:
            out.details["slip_action"] = res.action.to_dict()
            if keep_traces:
                out.traces["slip"] = res.traces
        fit_start, cpu_start = time.perf_counter(), time.process_time()
        try:
            diagnostics: dict[str, float] = {}
            mu, warns, interval = estimate_mu(res, noise, rng, diagnostics,
                                              config.slip_envelope)
            fits.append(_SlideFit(mu, warns, interval, diagnostics))
        except (EstimationError, ArithmeticError) as exc:
            failures.append(str(exc))
        out.details["wall_fits"] = (out.details.get("wall_fits", 0.0)
                                    + time.perf_counter() - fit_start)
        _add_cpu(out, "cpu_fits", cpu_start)
    if not fits:
        raise EstimationError(failures[0])
    fit = _median_of_slides(fits, config.slip_repeats)
    out.details.setdefault("diagnostics", {}).update(fit.diagnostics)
    out.estimates["mu"] = fit.mu
    out.intervals["mu"] = fit.interval
    out.warnings += [f"slip probe: {w}" for w in fit.warnings]
    if failures:
        out.warnings.append(f"slip probe: {len(failures)} of {config.slip_repeats} slides "
                            f"gave no estimate: {failures[0]}")
    out.friction_valid = True


def _median_of_slides(fits: list[_SlideFit], asked: int) -> _SlideFit:
    """One mu from several slides: their median (a slide's own where there is one), with
    the slide nearest it giving the warnings; the log-sd of its interval is the median
    slide's, and the slides' spread (their log-sd) added in quadrature.  The diagnostics are
    the slides' means, with ``mu_trials``, half the log-range of the slides' mu (0 for one
    slide), only where all ``asked`` slides gave a mu: the spread of those that did would say
    they agree when the others could not be compared (an error model that reads it then
    gives no interval)."""
    mus = np.array([f.mu for f in fits])
    mu = float(np.median(mus))
    nearest = fits[int(np.argmin(np.abs(np.log(mus / mu))))]
    diagnostics = {k: float(np.mean([f.diagnostics[k] for f in fits]))
                   for k in nearest.diagnostics if all(k in f.diagnostics for f in fits)}
    if len(fits) == asked:
        diagnostics["mu_trials"] = 0.5 * float(np.log(mus.max() / mus.min()))
    if len(fits) == 1:
        return _SlideFit(mu, nearest.warnings, nearest.interval, diagnostics)
    lo, hi = nearest.interval
    sd = math.hypot(math.log(hi / lo) / (2 * Z95), float(np.std(np.log(mus), ddof=1)))
    return _SlideFit(mu, nearest.warnings, log_interval(mu, sd), diagnostics)


def apply_calibration(shape: str, size: float, calibration: Calibration,
                      out: ProbeOutcome) -> None:
    """Apply ``calibration`` to complete estimates of a piece of ``shape`` and ``size``.

    The intervals of K1, K2, B move with the estimates.  Where the calibration has an error
    model (:class:`estimators.calibration.ErrorModel`), the 95 % intervals of g1, tau1 and
    mu are its ``exp(+-half_width)`` around the calibrated estimate, from the probes'
    diagnostics in ``out.details["diagnostics"]`` (NaN where one is missing),
    ``details["error_half_width"]`` keeps the half-widths, and
    ``details["reliable_half_width"]`` and ``details["reliable_diagnostics"]`` the model's
    own widths and diagnostic limits for :attr:`ProbeOutcome.reliable`, where it has them
    (a warning names the diagnostics past their limits).  Where the model has a noisy model
    and the food's traces carry sensor noise (:func:`estimators.calibration.noisy_traces`),
    that one gives the widths and the limits.
    """
    require_type("calibration", calibration, Calibration, "a Calibration")
    require_type("out", out, ProbeOutcome, "a ProbeOutcome")
    est = out.estimates
    if not (out.visco_valid and out.friction_valid
            and all(math.isfinite(est[k]) and est[k] > 0 for k in PARAM_NAMES)):
        out.warnings.append("not calibrated: the estimates are incomplete")
        return
    own = dict(est)
    try:
        fixed, warns = calibration.apply(shape, size, own, out.details.get("diagnostics", {}))
    except EstimationError as exc:
        out.warnings.append(f"not calibrated: {exc}")
        if calibration.error_model is not None:  # its intervals are for calibrated values
            for k in _modelled_intervals(calibration.error_model.targets):
                out.intervals[k] = (math.nan, math.nan)
                out.warnings.append(f"no {k} interval: the estimates are not calibrated")
        return
    for k in VISCO_NAMES:
        ratio = fixed[k] / est[k]
        lo, hi = out.intervals.get(k, (math.nan, math.nan))
        out.intervals[k] = (lo * ratio, hi * ratio)
    out.details["uncalibrated"] = own
    out.details["calibration"] = calibration.source
    est.update(fixed)
    out.warnings += warns
    if calibration.error_model is None:
        return
    # the model for this food: the noisy one where its traces carry sensor noise
    model = calibration.error_model.for_food(out.details.get("diagnostics", {}))
    widths = {}
    for k in model.targets:
        try:
            widths[k] = model.half_width(k, shape, size, own, out.details.get("diagnostics", {}))
        except EstimationError as exc:
            widths[k] = math.nan
            out.warnings.append(f"no {k} interval: {exc}")
    for k, width in _interval_half_widths(widths, est["g1"]).items():
        out.intervals[k] = _log_width_interval(est[k], width)
    out.details["error_half_width"] = widths
    if model.reliable_half_width:
        out.details["reliable_half_width"] = dict(model.reliable_half_width)
    if model.reliable_diagnostics:
        out.details["reliable_diagnostics"] = dict(model.reliable_diagnostics)
        past = out.diagnostics_past_limits()
        if past:
            out.warnings.append("not reliable: the probes did not measure this food "
                                f"reproducibly ({', '.join(past)}, past the error model's "
                                "limits)")


_VISCO_SPRINGS = ("K1", "K2", "B")


def _modelled_intervals(targets: tuple[str, ...]) -> tuple[str, ...]:
    """The parameters whose intervals an error model with ``targets`` gives."""
    return (*ERROR_TARGETS, *(_VISCO_SPRINGS if "K_el" in targets else ()))


def _interval_half_widths(widths: dict[str, float], g1: float) -> dict[str, float]:
    """Log half-widths by parameter from an error model's (by target): g1, tau1 and mu its
    own; where it has K_el, K1 = (1 - g1) K_el, K2 = g1 K_el and B = tau1 K2 add their
    parts in quadrature (log(1 - g1) moves g1 / (1 - g1) times as much as log g1)."""
    out = {k: widths[k] for k in ERROR_TARGETS}
    if "K_el" in widths:
        w_k, w_g, w_t = widths["K_el"], widths["g1"], widths["tau1"]
        out["K1"] = math.hypot(w_k, g1 / (1.0 - g1) * w_g)
        out["K2"] = math.hypot(w_k, w_g)
        out["B"] = math.sqrt(w_k**2 + w_g**2 + w_t**2)
    return out


def _log_width_interval(value: float, half_width: float) -> tuple[float, float]:
    """``value * exp(+-half_width)``; (0, inf) where the half-width is too wide for a float
    (an error model fitted on a user's own foods can predict one), NaN where it is NaN."""
    if half_width > MAX_LOG_HALF_WIDTH:
        return 0.0, math.inf
    return value * math.exp(-half_width), value * math.exp(half_width)



def run_probes(pieces: tuple[Piece, ...], config: ProbeConfig, geometry: Geometry | None = None,
               keep_traces: bool = False, noise: float = 0.0, seed: int = 0,
               calibration: Calibration | None = None, workers: int = 1,
               runs: ProbeRuns | None = None) -> ProbeOutcome:
    """Run both probes on the centre piece and estimate its parameters, with 95 % intervals.

    ``noise`` adds white sensor noise (sd as a share of each trace's peak) from a generator
    seeded with ``seed`` before estimation; ``calibration`` (:mod:`estimators.calibration`,
    e.g. ``PROBE_CALIBRATIONS[preset]`` for a preset's probes) corrects the probes' systematic
    errors, with the uncorrected values kept in ``details["uncalibrated"]``.  Never raises
    for a failed estimate or a diverged probe: the affected parameters are NaN, the
    ``*_valid`` flag is False and ``warnings`` says why.

    ``workers`` > 1 runs the probes' simulations (every relaxation clamp and slide) at once
    on that many processes (:func:`fetch_env.parallel.run_ahead`) before the fits: the same
    estimates as ``workers=1``, sooner on a machine with cores to spare; the CPU times in
    ``details`` are then this process's only.

    ``runs``: the probes' simulations of this piece already run (:func:`simulate_probes`,
    with the same ``config`` and ``geometry``); only the fits run then, and the outcome is
    the one a run without them gives (``workers`` is not used).

    Raises:
        fetch_env.parallel.WorkerLostError: a worker process died mid-run.
        InvalidParameterError: ``runs`` simulated for another piece, config or geometry.
    """
    require_finite("noise", noise)
    require(0.0 <= noise <= 0.5, "noise", noise, "in [0, 0.5]")
    require_int("seed", seed)
    require(seed >= 0, "seed", seed, ">= 0")
    require_int("workers", workers)
    require(workers >= 1, "workers", workers, ">= 1")
    require_type("calibration", calibration, Calibration | None, "a Calibration or None")
    _check_probe_args(None, config, geometry)
    require_type("runs", runs, ProbeRuns | None, "a ProbeRuns (simulate_probes) or None")
    wall, cpu = time.perf_counter(), time.process_time()
    k = probe_piece_index(pieces)
    piece = dataclasses.replace(pieces[k], x=0.0, y=0.0)
    if runs is not None:
        runs.check_for(piece, config, geometry)
    rng = np.random.default_rng(seed)
    nan = (math.nan, math.nan)
    out = ProbeOutcome(estimates=dict.fromkeys(PARAM_NAMES, math.nan), visco_valid=False,
                       friction_valid=False, wall_time=0.0, piece_index=k,
                       intervals=dict.fromkeys(PARAM_NAMES, nan))
    drift = reads_drift(calibration)
    if runs is not None:
        clamps, slides = list(runs.clamps), list(runs.slides)
    elif workers > 1:
        clamps, slides = _runs_ahead(piece, config, geometry, workers)
    else:
        clamps, slides = None, None
    out.details["workers"] = workers
    relaxation = functools.partial(_relaxation_probe, drift_diagnostics=drift, ahead=clamps)
    slip = functools.partial(_slip_probe, ahead=slides)
    for name, probe in (("relaxation", relaxation), ("slip", slip)):
        try:
            probe(piece, config, geometry, noise, rng, out, keep_traces)
        except (EstimationError, SimulationDivergedError, ArithmeticError) as exc:
            out.warnings.append(f"{name} probe: {exc}")
    if calibration is not None:
        apply_calibration(piece.shape, piece.size, calibration, out)
    out.wall_time = time.perf_counter() - wall
    _add_cpu(out, "cpu_time", cpu)
    return out


def reads_drift(calibration: Calibration | None) -> bool:
    """Whether the probes must compute the drift diagnostics, which cost a fit: where the
    calibration reads them (as features, or in its error model's reliability limits), or
    where none is applied (a run that a calibration may be fitted on)."""
    if calibration is None:
        return True
    read = set(calibration.feature_names)
    model = calibration.error_model
    for m in (model, model and model.noisy):
        if m is not None:
            read |= set(m.reliable_diagnostics)
    return not read.isdisjoint(DRIFT_DIAGNOSTICS)


@dataclass(frozen=True)
class ProbeRuns:
    """The probes' simulations of one piece, before any fit (:func:`simulate_probes`): each
    relaxation clamp and each slide, in order, as its ``SimResult`` or the error it raised.

    :func:`run_probes` given them fits them instead of simulating again, with the outcome
    a run without them gives: one simulation fitted with several noise seeds or
    calibrations, or the fits' cost timed alone (``benchmarks/bench_fits.py``).
    """

    piece: Piece  # the probed piece, moved to the origin as the probes place it
    config: ProbeConfig
    geometry: Geometry | None
    clamps: tuple[Any, ...]
    slides: tuple[Any, ...]

    def check_for(self, piece: Piece, config: ProbeConfig, geometry: Geometry | None) -> None:
        """Raise :class:`InvalidParameterError` unless these are the simulations of
        ``piece`` (at the origin) with ``config`` and ``geometry``."""
        for name, mine, theirs in (("piece", self.piece, piece), ("config", self.config, config),
                                   ("geometry", self.geometry, geometry)):
            if mine != theirs:
                raise InvalidParameterError(
                    f"runs were simulated for another {name} than the one given "
                    f"(simulate_probes with the same pieces, config and geometry)")


def simulate_probes(pieces: tuple[Piece, ...], config: ProbeConfig,
                    geometry: Geometry | None = None, workers: int = 1) -> ProbeRuns:
    """Run the probes' simulations on the centre piece of ``pieces`` (every relaxation clamp
    and slide; on ``workers`` processes at once where > 1) without fitting them; pass the
    result to :func:`run_probes` as ``runs``.  A clamp or slide that fails keeps its error,
    which :func:`run_probes` reports as it would have.

    Raises:
        fetch_env.parallel.WorkerLostError: a worker process died mid-run.
    """
    require_int("workers", workers)
    require(workers >= 1, "workers", workers, ">= 1")
    _check_probe_args(None, config, geometry)
    piece = dataclasses.replace(pieces[probe_piece_index(pieces)], x=0.0, y=0.0)
    clamps, slides = _runs_ahead(piece, config, geometry, workers)
    return ProbeRuns(piece, config, geometry, tuple(clamps), tuple(slides))


def _runs_ahead(piece: Piece, config: ProbeConfig, geometry: Geometry | None,
                workers: int) -> tuple[list[Any], list[Any]]:
    """Every relaxation clamp and slide of the probes, run at once on ``workers`` processes:
    (the clamps, the slides), each a result or the error it raised."""
    tasks: list[Task] = [(relaxation_run, (piece, config, geometry, strain))
                         for strain in repeat_strains(config)]
    tasks += [(_slide_run, (piece, config, geometry, t)) for t in slide_times(config)]
    results = run_ahead(tasks, workers)
    n = config.relaxation_repeats
    return results[:n], results[n:]


def _add_cpu(out: ProbeOutcome, key: str, start: float) -> None:
    """Add this process's CPU time since ``start`` to ``out.details[key]`` [s]: what the step
    costs a core, whatever else the machine runs (the wall time follows the load)."""
    out.details[key] = out.details.get(key, 0.0) + time.process_time() - start


# Named probe settings: "env" is what the environments run at every reset (cheap);
# "measure" is what `food-fetch estimate` and the validation harness run: a 20 s hold, long
# enough for the slowest foods of the space (tau1 10 s; on 32 tuning foods tau1's 95th
# percentile was 18 % against the 6 s hold's 28 %, while a 1 ms relaxation step and a
# real-time 15 s hold at 2.5 ms were no better, 28 % and 30 %), and a 0.3 s slide, whose 30
# samples let estimate_friction find its plateau instead of falling back on the ratio's
# envelope (mu's median error on the 64 tuning foods 0.60 -> 0.52 %; its 95th percentile
# did not improve, 5.9 -> 7.0 %, until the envelope's quantile was raised).  Other holds,
# each calibrated on the 256 tuning foods and 8-fold cross-validated there (tau1 median /
# 95th percentile error, no noise): 14 s 2.7 / 21 %, 20 s 2.8 / 19 %, 27 s 2.8 / 22 %, 40 s
# 3.7 / 32 % (over a long hold the moment drifts by more than the relaxation left); log steps
# of 3 % instead of 5 % at 20 s: 3.1 / 19 %.  None is better than 20 s by more than the
# scatter between neighbours.  Other slides (the 256 tuning foods, uncalibrated, mu's median /
# 95th percentile error): this 2 mm in 0.3 s 0.09 / 4.1 %; 4 mm in 0.6 s 0.04 / 4.1 %; 4 mm
# in 0.3 s 0.06 / 5.0 %; slip strain 0.2 0.36 / 9.3 %, 0.05 0.15 / 4.5 %.  mu's tail is soft,
# large or high-friction pieces that roll and stick-slip under the blades, whatever the slide.
CALIBRATION_FILE = Path(__file__).with_name("assets") / "probe_calibration.json"


def _check_run_args(result: Any, experiment: str, noise: Any, rng: Any) -> None:
    """Refuse a run that is not a ``SimResult`` of ``experiment``, a noise outside [0, 0.5]
    and an ``rng`` that is not a numpy Generator or None."""
    require_type("result", result, SimResult, f"a SimResult of the {experiment} experiment")
    require(result.experiment == experiment, "result", result.experiment,
            f"a run of the {experiment} experiment")
    require_finite("noise", noise)
    require(0.0 <= noise <= 0.5, "noise", noise, "in [0, 0.5]")
    require_type("rng", rng, np.random.Generator | None, "a numpy.random.Generator or None")


def _check_probe_args(piece: Any, config: Any, geometry: Any) -> None:
    """Refuse a piece (where given) that is not a ``Piece``, a config that is not a
    ``ProbeConfig`` and a geometry that is not a ``Geometry`` or None."""
    if piece is not None:
        require_type("piece", piece, Piece, "a Piece")
    require_type("config", config, ProbeConfig, "a ProbeConfig")
    require_type("geometry", geometry, Geometry | None, "a Geometry or None")


def load_calibrations(path: Path = CALIBRATION_FILE) -> dict[str, Calibration]:
    """The shipped calibrations by preset name (none where the file is absent)."""
    require_type("path", path, str | os.PathLike, "a file name")
    path = Path(path)
    if not path.exists():
        return {}
    data = json.loads(path.read_text())
    return {name: Calibration.from_dict(entry) for name, entry in data.items()}


PROBE_PRESETS: dict[str, ProbeConfig] = {
    "env": ProbeConfig(),
    "measure": ProbeConfig(hold=20.0, slide_time=0.3, slip_envelope="per_blade"),
    # measure's probes with seven relaxation clamps at squeezes 0.0564-0.0636, whose medians
    # shrink the tails of g1 and tau1 a single clamp leaves (tau1's 95th percentile 17 -> 10 %
    # on the tuning foods, cross-validated; ProbeConfig.relaxation_repeats), and K1, K2, B
    # at the camera's contact angle (ProbeConfig.contact_angle)
    "repeated": ProbeConfig(hold=20.0, slide_time=0.3, slip_envelope="per_blade",
                            relaxation_repeats=7, contact_angle="camera"),
    # repeated's probes with a relaxation clamp whose blade contact is ~300 times stiffer
    # (only the blades', ProbeConfig.relaxation_contact_ratio; a cube's contact mesh finer),
    # friction nearly rigid (impratio 1e4: a held contact creeps ~ 1 / impratio) and a 1 ms
    # step that keeps so stiff a contact stable: the held moment then relaxes as the food
    # does (uncalibrated, one clamp, tuning foods: tau1 within about 0.5 % median where the
    # measure probes read 5 %; docs/estimator_validation.md), at about 5x the probes' cost
    #
    # Its slip probe starts the blades 0.1 mm from the food (slip_gap) and squeezes it by 3 %
    # (slip_strain) at a 2.5 ms step, so the blades lean in by a third of the angle they did
    # and their tips press less into a cube's sides (ProbeConfig.slip_gap), and reads the
    # two half-spoons' envelopes less the sensor's noise.  On the 512 tuning foods,
    # uncalibrated, mu's |error| (median / 90th / 95th percentile): the measure probes' slip
    # 0.10 / 2.1 / 4.2 %; gap 0.1 mm with squeeze 0.1 0.15 / 2.0 / 3.5 %, 0.05 0.08 / 1.2 /
    # 1.9 %, 0.03 0.07 / 0.9 / 1.5 %; 0.03 at 5 ms 0.05 / 0.8 / 1.3 %, at 2.5 ms 0.03 / 0.7 /
    # 1.3 %.  Slides of 0.2 or 0.45 s, 3 mm, a slower clamp or a longer hold moved the 95th
    # percentile by under 0.2 points either way.  The price is noise: with 1 % noise the smaller
    # forces read mu at 1.8 / 6.0 / 8.6 % (the measure slip 2.3 / 4.5 / 6.3 %).
    #
    # Which foods a single slide misses is chaotic (a slide of another speed misses others),
    # so the probe slides several times (five, below; first three, over 0.3, 0.45 and 0.2 s)
    # and takes the median (ProbeConfig.slip_repeats): on the 512 tuning foods, uncalibrated,
    # with three slides mu's |error| went
    # from 0.03 / 0.7 / 1.3 % (one slide) to 0.04 / 0.6 / 1.0 %, foods past 1.4 % from 19
    # to 14, the worst from 15 to 3.4 %; with 1 % noise from 1.80 / 6.0 / 8.6 % to 1.50 /
    # 4.5 / 5.6 % (benchmarks/slip_probe.py).  The slides' spread (diagnostic mu_trials, an
    # input of the error model) says which foods to trust: the 302 whose slides agreed within
    # 0.1 % were within 1.7 %.
    #
    # With sensor noise each slide reads the level its force ratio slips at from every
    # sample near it, not from one high quantile ("per_blade_slipping", SLIP_ENVELOPES),
    # and only where the blades press firmly (NOISY_SLIP_MIN_SHARE): without noise it reads
    # as before; with 1 % noise mu's |error| over the three slides (median / 90th / 95th
    # percentile / max) is 0.87 / 2.7 / 3.1 / 6 %, against 1.38 / 3.7 / 4.7 / 7 % for the
    # denoised envelope (512 tuning foods, benchmarks/slip_probe.py; read from every
    # gripping sample, 0.77 / 2.8 / 4.1 / 19 % and 1.50 / 4.5 / 5.6 / 16 %).  That level
    # still reads mu low under noise (mean -1.1 %: sticking samples just below mu that the
    # noise lifts into the slipping window), so the preset reads it less that bias,
    # extrapolated away ("per_blade_simex", fetch_env.slip_simex): 0.40 / 1.5 / 1.8 / 3.1 %,
    # mean -0.17 %, on the same slides with one noise draw each.
    #
    # Five slides rather than three (the next two of slide_times: 0.675 and 0.133 s, about
    # 0.3 s more of probes a food): under noise the median averages more of it away, and
    # the slides' spread then tells the foods the noise pushed far from those it did not.
    # On the 512 tuning foods' slides, three 1 % noise draws each (1536 readings,
    # uncalibrated; median / 90th / 95th percentile / max of |mu error|): three slides
    # 0.47 / 1.5 / 2.0 / 6.9 %, 21 readings past 3 %; five 0.40 / 1.3 / 1.7 / 5.3 %, 10.
    # To flag every reading past 3 % by the slides' spread (half their log-range) alone, three
    # slides need a limit of 0.0033, which flags 1168 of the 1462 readings within 2 %; five
    # 0.036, which flags 92 of 1484; to flag the one reading past 5 % (at 5.3 %, a half-range
    # of 0.068), 0.06, which flags 27 of 1484 and 2 of the 3 past 4 % (the limit
    # benchmarks.validate_estimators.RELIABILITY sets).  Without noise (the harness's tuning
    # run) 0.04 / 0.58 / 1.03 / 3.4 %, 14 foods past 1.4 %, went to 0.04 / 0.63 / 1.00 /
    # 3.4 %, 12.  Seven
    # slides did little better (with noise 0.36 / 1.3 / 1.6 / 4.4 %, 7 past 3 %, but their
    # spread flags 115 to flag those), and the longest read a few foods low without noise
    # (the 0.675 and 1.01 s slides alone 2.6 and 3.3 % at the 95th percentile, the 0.3 s
    # one 1.3 %).
    "precise": ProbeConfig(hold=20.0, slide_time=0.3, slip_envelope="per_blade_simex",
                           relaxation_repeats=7, contact_angle="camera",
                           relaxation_timestep=0.001, relaxation_impratio=1e4,
                           relaxation_contact_ratio=2.25, slip_gap=RELAXATION_GAP,
                           slip_strain=0.03, slip_timestep=0.0025, slip_repeats=5),
}

# Calibrations of the presets' systematic errors, fitted on the validation harness's tuning
# foods (benchmarks/validate_estimators.py --fit-calibration): they hold only for the
# settings of the preset they were fitted for.  A key "PRESET/LAYOUT-SCENES" holds the
# preset's calibration fitted on the pieces an environment of that layout and scene space
# draws (calibration_for).
PROBE_CALIBRATIONS: dict[str, Calibration] = load_calibrations()


def scene_calibration_key(preset: str, layout: str, scenes: str) -> str:
    """The key of ``preset``'s calibration fitted on the pieces of ``layout``'s scenes in the
    scene space ``scenes`` (in :data:`PROBE_CALIBRATIONS` where one is shipped)."""
    return f"{preset}/{layout}-{scenes}"


def calibration_for(preset: str, layout: str | None = None,
                    scenes: str | None = None) -> Calibration | None:
    """The shipped calibration of ``preset``'s probes for an environment's observations.

    Where one was fitted on the pieces of ``layout``'s scenes in ``scenes`` (the Block
    scenes of the study space, whose foods span a narrower range than the food space: 10-20
    mm, g1 0.2-0.6, tau1 1-6 s, mu 0.15-0.6), that one: an instrument is calibrated against
    reference samples like those it will measure, and a log-linear correction fitted on
    them fits them better than one fitted over the whole food space (on 256 Block scenes of
    seed 95000, 8-fold cross-validated, the ``measure`` probes' tau1 median |error| 1.3 %
    against the food-space calibration's 1.7 %; docs/estimator_validation.md).  Else the
    preset's food-space calibration; None for a preset without one.
    """
    if layout is not None and scenes is not None:
        own = PROBE_CALIBRATIONS.get(scene_calibration_key(preset, layout, scenes))
        if own is not None:
            return own
    return PROBE_CALIBRATIONS.get(preset)
