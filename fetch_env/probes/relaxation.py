"""The relaxation probe: clamps held while the food relaxes, and the fits of their moment
that give K1, K2, B, g1 and tau1 (the full fit for the contact angle and timing, the hold
alone for the values), with the median over repeated clamps."""

from __future__ import annotations

import dataclasses
import math
import time
from dataclasses import dataclass
from typing import Any

import numpy as np

from estimators import (
    ClampGeometry,
    EstimationError,
    HoldEstimate,
    SLSParams,
    ViscoelasticEstimate,
    estimate_from_hold,
    estimate_full_fit,
    estimate_three_step,
)
from estimators.uncertainty import DRIFT_DIAGNOSTICS, hold_with_intervals
from estimators.uncertainty import drift_diagnostics as uncertainty_drift
from fetch_env.controller import PHASE_CODE, FetchAction, FetchSimulator, SimResult, TimeScale
from fetch_env.errors import require, require_finite
from fetch_env.layouts import Piece
from fetch_env.parallel import outcome
from fetch_env.probes.config import PROBE_SYSTEMATIC_SD, ProbeConfig, repeat_strains
from fetch_env.probes.placement import first_contact_angle, probe_angle
from fetch_env.probes.results import ProbeOutcome, _add_cpu
from fetch_env.probes.traces import _check_run_args, _mean_moment, _noisy
from fetch_env.scene import Geometry
from fetch_env.spaces import VISCO_NAMES

HOLD_SKIP = 0.1  # [s] start of the relaxation hold left out of the fit (servo catching up)
# [s] start of the hold left out of the hold-only fit of g1 and tau1: a round piece that rocks
# as the blades close is still settling into the clamp (its moment rising, then falling faster
# than the material relaxes) up to ~0.25 s after t_d.  On seeds 5000-5063, 0.2 / 0.25 / 0.3 s
# gave g1 median errors of 6.1 / 5.5 / 5.3 % and 75th percentiles of 12.8 / 12.3 / 13.1 %;
# for tau1 on seeds 5000-5127, 0.1 / 0.25 / 0.5 / 0.75 s gave
# medians of 6.5 / 5.9 / 6.0 / 7.2 % and 75th percentiles of 13.2 / 11.6 / 11.8 / 15.3 %.
HOLD_SETTLE = 0.25
CLAMP_WEIGHT = 0.3  # full fit: clamp residuals against the hold (docs/reproducing.md)


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


def _relaxation_simulator(piece: Piece, config: ProbeConfig,
                          geometry: Geometry | None) -> FetchSimulator:
    """The simulator of ``piece`` alone under ``config``'s relaxation settings."""
    return FetchSimulator((piece,), geometry, impratio=config.relaxation_impratio,
                          timestep=config.relaxation_timestep,
                          relaxation_contact_ratio=config.relaxation_contact_ratio,
                          warmstart=config.relaxation_warmstart)


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
