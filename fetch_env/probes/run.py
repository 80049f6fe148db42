"""Both probes on one piece (:func:`run_probes`), and their simulations run ahead of the
fits (:func:`simulate_probes`, :class:`ProbeRuns`)."""

from __future__ import annotations

import dataclasses
import functools
import math
import time
from dataclasses import dataclass
from typing import Any

import numpy as np

from estimators import EstimationError
from estimators.calibration import Calibration
from fetch_env.errors import (
    InvalidParameterError,
    SimulationDivergedError,
    require,
    require_finite,
    require_int,
    require_type,
)
from fetch_env.layouts import Piece
from fetch_env.parallel import Task, run_ahead
from fetch_env.probes.calibrated import apply_calibration, reads_drift
from fetch_env.probes.config import (
    PARAM_NAMES,
    ProbeConfig,
    _check_probe_args,
    repeat_strains,
    slide_times,
)
from fetch_env.probes.placement import probe_piece_index
from fetch_env.probes.relaxation import _relaxation_probe, relaxation_run
from fetch_env.probes.results import ProbeOutcome, _add_cpu
from fetch_env.probes.slip import _slide_run, _slip_probe
from fetch_env.probes.truth import true_parameters_exact
from fetch_env.scene import Geometry


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
        clamps, slides, _ = _runs_ahead(piece, config, geometry, workers)
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
    # the piece's elastic-twin truth (true_parameters_exact) or the error it raised, where
    # simulate_probes ran it beside the probes (truth=True); None where it did not
    truth: dict[str, float] | BaseException | None = None

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
                    geometry: Geometry | None = None, workers: int = 1,
                    truth: bool = False) -> ProbeRuns:
    """Run the probes' simulations on the centre piece of ``pieces`` (every relaxation clamp
    and slide; on ``workers`` processes at once where > 1) without fitting them; pass the
    result to :func:`run_probes` as ``runs``.  A clamp or slide that fails keeps its error,
    which :func:`run_probes` reports as it would have.

    ``truth``: also run the piece's elastic twin (:func:`true_parameters_exact`, the truth
    the estimates are held to) among the same tasks, so that on several workers it runs
    beside the probes instead of after them; its result, or the error it raised, is the
    returned ``truth``.

    Raises:
        fetch_env.parallel.WorkerLostError: a worker process died mid-run.
    """
    require_int("workers", workers)
    require(workers >= 1, "workers", workers, ">= 1")
    require_type("truth", truth, bool, "True or False")
    _check_probe_args(None, config, geometry)
    piece = dataclasses.replace(pieces[probe_piece_index(pieces)], x=0.0, y=0.0)
    clamps, slides, twin = _runs_ahead(piece, config, geometry, workers, truth)
    return ProbeRuns(piece, config, geometry, tuple(clamps), tuple(slides), twin)


def _runs_ahead(piece: Piece, config: ProbeConfig, geometry: Geometry | None,
                workers: int, truth: bool = False) -> tuple[list[Any], list[Any], Any]:
    """Every relaxation clamp and slide of the probes, and where ``truth`` the elastic twin,
    run at once on ``workers`` processes: (the clamps, the slides, the twin's truth or
    None), each a result or the error it raised.  The twin goes first: it is the longest
    single task, so the pool does not wait on it at the end."""
    tasks: list[Task] = [(true_parameters_exact, (piece, config, geometry))] if truth else []
    tasks += [(relaxation_run, (piece, config, geometry, strain))
              for strain in repeat_strains(config)]
    tasks += [(_slide_run, (piece, config, geometry, t)) for t in slide_times(config)]
    results = run_ahead(tasks, workers)
    twin = results.pop(0) if truth else None
    n = config.relaxation_repeats
    return results[:n], results[n:], twin
