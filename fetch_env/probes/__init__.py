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

The package, one idea a module: :mod:`~fetch_env.probes.config` (the settings and the
repeats they imply), :mod:`~fetch_env.probes.presets` (the named settings),
:mod:`~fetch_env.probes.placement` (which piece, at what angle),
:mod:`~fetch_env.probes.relaxation` and :mod:`~fetch_env.probes.slip` (the two probes and
their fits; each slide's mu is read by :mod:`estimators.slip_level`),
:mod:`~fetch_env.probes.truth` (the true values), :mod:`~fetch_env.probes.calibrated` (the
shipped calibrations), :mod:`~fetch_env.probes.run` (both probes on one piece) and
:mod:`~fetch_env.probes.results` (what they return).  Every public name is importable from
``fetch_env.probes`` itself.
"""


from __future__ import annotations

from estimators.slip_level import (
    ENVELOPE_QUANTILE,
    NOISE_QUANTILE_Z,
    NOISY_SLIP_MIN_SHARE,
    SLIP_SIMEX,
    SLIPPING_ITERATIONS,
    SLIPPING_TAIL,
)
from fetch_env.probes.calibrated import (
    CALIBRATION_FILE,
    PROBE_CALIBRATIONS,
    apply_calibration,
    calibration_for,
    load_calibrations,
    reads_drift,
    scene_calibration_key,
)
from fetch_env.probes.config import (
    CONTACT_ANGLES,
    MAX_RELAXATION_REPEATS,
    MAX_SLIP_REPEATS,
    PARAM_NAMES,
    PROBE_SYSTEMATIC_SD,
    SLIP_ENVELOPES,
    SLIP_REPEAT_TIME_RATIO,
    ContactAngle,
    ProbeConfig,
    SlipEnvelope,
    repeat_strains,
    slide_times,
)
from fetch_env.probes.placement import first_contact_angle, probe_angle, probe_piece_index
from fetch_env.probes.presets import PROBE_PRESETS
from fetch_env.probes.relaxation import (
    CLAMP_WEIGHT,
    HOLD_SETTLE,
    HOLD_SKIP,
    estimate_viscoelastic,
    relaxation_run,
)
from fetch_env.probes.results import RELIABLE_HALF_WIDTH, ProbeOutcome
from fetch_env.probes.run import ProbeRuns, run_probes, simulate_probes
from fetch_env.probes.slip import estimate_mu, slip_run
from fetch_env.probes.truth import (
    TWIN_MAX_LOST_SHARE,
    TWIN_SHIFTS,
    elastic_stiffness,
    nominal_stiffness,
    true_parameters,
    true_parameters_exact,
)

__all__ = [
    "CALIBRATION_FILE",
    "CLAMP_WEIGHT",
    "CONTACT_ANGLES",
    "ENVELOPE_QUANTILE",
    "HOLD_SETTLE",
    "HOLD_SKIP",
    "MAX_RELAXATION_REPEATS",
    "MAX_SLIP_REPEATS",
    "NOISE_QUANTILE_Z",
    "NOISY_SLIP_MIN_SHARE",
    "PARAM_NAMES",
    "PROBE_CALIBRATIONS",
    "PROBE_PRESETS",
    "PROBE_SYSTEMATIC_SD",
    "RELIABLE_HALF_WIDTH",
    "SLIPPING_ITERATIONS",
    "SLIPPING_TAIL",
    "SLIP_ENVELOPES",
    "SLIP_REPEAT_TIME_RATIO",
    "SLIP_SIMEX",
    "TWIN_MAX_LOST_SHARE",
    "TWIN_SHIFTS",
    "ContactAngle",
    "ProbeConfig",
    "ProbeOutcome",
    "ProbeRuns",
    "SlipEnvelope",
    "apply_calibration",
    "calibration_for",
    "elastic_stiffness",
    "estimate_mu",
    "estimate_viscoelastic",
    "first_contact_angle",
    "load_calibrations",
    "nominal_stiffness",
    "probe_angle",
    "probe_piece_index",
    "reads_drift",
    "relaxation_run",
    "repeat_strains",
    "run_probes",
    "scene_calibration_key",
    "simulate_probes",
    "slide_times",
    "slip_run",
    "true_parameters",
    "true_parameters_exact",
]
