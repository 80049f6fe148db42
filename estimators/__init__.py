"""Estimators of food viscoelasticity (K1, K2, B) and friction (mu) from sensor traces.

Pure numpy/scipy: never imports MuJoCo, so the same code runs on a real robot's logs.

Modules (units: s, rad, m, N, N m; see docs/study.md for eqs. 1-7):

* :mod:`estimators.sls` -- standard linear solid in the half-spoon's rotational form:
  :class:`ClampGeometry`, :class:`SLSParams` (with Prony ``g1, tau1`` conversion) and the forward
  model :func:`moment_trace` (exact closed form, integrating-factor quadrature, ``solve_ivp``).
* :mod:`estimators.relaxation` -- ``K1, K2, B`` from one clamp-and-hold:
  :func:`estimate_three_step` (the study's method) and :func:`estimate_full_fit` (one least-squares
  fit of the whole trace with 95 % intervals); both return :class:`ViscoelasticEstimate`.
  :func:`estimate_from_hold` gives them (and ``g1, tau1``) from the hold alone, for clamps
  that do not rise as an SLS would.
* :mod:`estimators.friction` -- ``mu`` by induced slippage: :func:`estimate_friction`.
* :mod:`estimators.slip_level` -- ``mu`` from a slide's forces as the simulated probes
  read it: each half-spoon's force ratio at its slipping level, less the noise's bias
  (:func:`~estimators.slip_level.read_mu`, with :mod:`estimators.slip_simex`).
* :mod:`estimators.errors` -- :class:`EstimationError` (a ``ValueError``) for unusable input.
"""

from estimators.errors import EstimationError
from estimators.friction import FrictionEstimate, estimate_friction
from estimators.relaxation import (
    HoldEstimate,
    ViscoelasticEstimate,
    estimate_from_hold,
    estimate_full_fit,
    estimate_three_step,
)
from estimators.sls import ClampGeometry, SLSParams, moment_trace, steady_moment
from estimators.trace_files import RecordedTraces, TraceFileError, load_traces

__all__ = [
    "ClampGeometry",
    "EstimationError",
    "FrictionEstimate",
    "HoldEstimate",
    "RecordedTraces",
    "SLSParams",
    "TraceFileError",
    "ViscoelasticEstimate",
    "estimate_friction",
    "estimate_from_hold",
    "estimate_full_fit",
    "estimate_three_step",
    "load_traces",
    "moment_trace",
    "steady_moment",
]
