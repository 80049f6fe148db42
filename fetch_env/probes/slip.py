"""The induced-slip probe: slides of the clamped piece toward the plate, each read for mu
from the two half-spoons' force ratios by :mod:`estimators.slip_level` (Coulomb bounds each
by mu; a stick-slipping piece reaches it only while slipping), and the median over repeated
slides."""

from __future__ import annotations

import dataclasses
import math
import time
from dataclasses import dataclass
from typing import Any

import numpy as np

from estimators import EstimationError
from estimators.slip_level import (
    SLIP_ENVELOPES,
    SLIP_FORCES,
    SlipEnvelope,
    read_mu,
)
from estimators.uncertainty import Z95, log_interval
from fetch_env.controller import PHASE_CODE, FetchAction, FetchSimulator, SimResult
from fetch_env.errors import SimulationDivergedError, require
from fetch_env.layouts import Piece
from fetch_env.parallel import outcome
from fetch_env.probes.config import ProbeConfig, _check_probe_args, slide_times
from fetch_env.probes.placement import probe_angle
from fetch_env.probes.results import ProbeOutcome, _add_cpu
from fetch_env.probes.traces import _check_run_args, _noisy
from fetch_env.scene import Geometry

# The slip probe is sampled at every physics step (run_probes; at 5 ms, 200 Hz gave
# estimate_friction the 20 samples of a 0.15 s slide; at 100 Hz only the envelope could be
# used).  Seeds 5000-5191, |mu error| median / 75th / 95th percentile / max, 5 ms step: 0.3 s
# slide at 100 Hz 0.2 / 1.3 / 6.6 / 28 %; 0.2 s, 100 Hz 0.2 / 1.4 / 5.6 / 48 %; 0.15 s,
# 100 Hz 0.2 / 1.3 / 7.2 / 34 %; 0.15 s, 200 Hz 0.1 / 1.0 / 4.9 / 24 %; at the
# 10 ms step, every step (100 Hz): 0.1 / 1.2 / 4.6 / 13 %.


def estimate_mu(result: SimResult, noise: float = 0.0, rng: np.random.Generator | None = None,
                diagnostics: dict[str, float] | None = None,
                envelope: SlipEnvelope = "sum"
                ) -> tuple[float, list[str], tuple[float, float]]:
    """mu from a slip run, with a 95 % interval: :func:`estimators.slip_level.read_mu` on
    its traces, the slide and the settle before the blades touch told by its phases.
    ``noise`` (with ``rng``) adds white noise of that share of each force trace's peak
    first.  Raises :class:`EstimationError` when the trace cannot give mu."""
    _check_run_args(result, "slip", noise, rng)
    require(isinstance(envelope, str) and envelope in SLIP_ENVELOPES, "envelope", envelope,
            f"one of {SLIP_ENVELOPES}")
    tr = result.traces
    f = {k: _noisy(tr[k], noise, rng) for k in SLIP_FORCES}
    return read_mu(tr["t"], f, tr["phase"] == PHASE_CODE["slide"],
                   tr["phase"] == PHASE_CODE["settle"], envelope, diagnostics)


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
