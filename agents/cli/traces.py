"""``food-fetch estimate --traces FILE``: the estimators on recorded sensor traces.

A real robot's log (CSV) or ``simulate --json`` output (schema: ``docs/traces_format.md``) is
read by :func:`estimators.load_traces` and estimated by :func:`estimate_recorded`, the one
place that picks the estimators: for the clamp, as the study's probes of ``food-fetch
estimate --probes study`` do (the full fit with the same clamp weight, or the three-step
method); for the slide, by default mu as the simulated probes read it
(:func:`estimators.slip_level.read_mu`: each half-spoon's force ratio at the level it slips at,
less the bias the sensor's noise puts into it), which holds on stick-slipping and noisy
slides where the study's plateau (:func:`estimators.estimate_friction`, ``mu_reading=
"study"``) reads a sticking level.  The ``precise`` probes' other readings (seven clamps'
medians, the calibration fitted for their clamp) belong to their own simulated clamps and
are not applied to a recorded run.  The report and ``--json`` have the simulated path's
shape, with every true value unknown ('-' / null).

The simulation's options (food, clamp, noise, seed, ...) are refused with ``--traces``: a
recorded run is what it is, and accepting them silently would suggest they changed something.
"""

from __future__ import annotations

import argparse
import math
import time
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np

from agents.cli.common import UsageError, finite, require_distinct, write_json
from agents.cli.estimate import NAMES, ProbeEstimate, print_report
from estimators import (
    EstimationError,
    FrictionEstimate,
    RecordedTraces,
    TraceFileError,
    ViscoelasticEstimate,
    estimate_friction,
    estimate_full_fit,
    estimate_three_step,
    load_traces,
)
from estimators.slip_level import SLIP_FORCES, read_mu
from fetch_env.probes.results import within_half_width
from fetch_env.study_probes import SIM_CLAMP_WEIGHT

# Options of ``estimate`` that keep their meaning with --traces (argparse dests).
TRACE_OPTIONS = frozenset({"traces", "L", "theta_0", "contact_angle", "probe", "method",
                           "mu_reading", "json"})
PROG = "food-fetch estimate"
# How mu is read from a recorded slide (estimate_recorded's mu_reading).
MuReading = Literal["slipping", "study"]
MU_READINGS: tuple[MuReading, ...] = ("slipping", "study")


class _NoteGiven(argparse._StoreAction):
    """A store action that also notes its option string in ``simulation_options``, so
    ``--traces`` can refuse a simulation option even when given its default value."""

    def __call__(
        self,
        parser: argparse.ArgumentParser,
        namespace: argparse.Namespace,
        values: Any,
        option_string: str | None = None,
    ) -> None:
        super().__call__(parser, namespace, values, option_string)
        namespace.simulation_options = (*namespace.simulation_options, option_string)


def add_traces_options(p: argparse.ArgumentParser) -> None:
    """Add ``--traces``, ``--L``, ``--theta-0``, ``--contact-angle`` to ``estimate``'s parser
    ``p`` and mark every option already there that only a simulation uses (call it after
    those are added)."""
    for action in p._actions:
        if type(action) is argparse._StoreAction and action.dest not in TRACE_OPTIONS:
            action.__class__ = _NoteGiven
    p.set_defaults(simulation_options=())
    g = p.add_argument_group(
        "recorded traces",
        "estimate from a file instead of simulating (schema: docs/traces_format.md); "
        "--probe both runs every probe the file has data for",
    )
    g.add_argument("--traces", default=None, metavar="FILE",
                   help="recorded sensor traces: a CSV file or 'simulate --json' output")
    g.add_argument("--L", type=finite(), default=None, metavar="M",
                   help="lever arm L [m] from the hinge axis to the contact section "
                   "(default: the file's)")
    g.add_argument("--theta-0", type=finite(), default=None, metavar="RAD",
                   help="hinge angle theta_0 [rad] at which the contact face is vertical "
                   "(default: the file's)")
    g.add_argument("--contact-angle", type=finite(), default=None, metavar="RAD",
                   help="hinge angle [rad] at which the faces first touch the piece, where "
                   "known (e.g. from a depth camera): the full fit uses it instead of the "
                   "one it detects (K1, K2, B scale with 1 / (sin theta_d - sin it))")
    g.add_argument("--mu-reading", choices=MU_READINGS, default=None,
                   help="how mu is read from the slide: 'slipping' (each half-spoon's force "
                   "ratio at the level it slips at, less the sensor noise's bias; needs the "
                   "slide marked by a phase column or slide_start) or 'study' (the study's "
                   "plateau of the ratio) (default: slipping)")


@dataclass
class SlipReading:
    """mu read from a recorded slide by :func:`estimators.slip_level.read_mu`: its 95 % interval
    (noise and model error), whether it counts as reliable, the reading's warnings and its
    diagnostics.  Reliable follows the uncalibrated probes' rule (the interval within
    ``fetch_env.probes.RELIABLE_HALF_WIDTH`` of mu), which a recorded slide does not meet:
    its interval always holds the probes' systematic 2 %
    (``estimators.slip_level.MU_SYSTEMATIC_SD``, a half-width of at least 4 %), since
    nothing calibrates the robot that logged it."""

    mu: float
    interval: tuple[float, float]
    reliable: bool
    warnings: list[str]
    diagnostics: dict[str, float]


@dataclass
class RecordedEstimates:
    """What :func:`estimate_recorded` got: each probe's estimate, or why it failed, and
    ``notes`` on how an estimate was read where it was not read as asked."""

    relaxation: ViscoelasticEstimate | None = None
    friction: FrictionEstimate | SlipReading | None = None
    failures: dict[str, str] = field(default_factory=dict)
    fit_time: float = math.nan
    notes: list[str] = field(default_factory=list)


def probes_to_run(traces: RecordedTraces, probe: str) -> tuple[str, ...]:
    """The probes ``probe`` asks for: ``"both"`` is every probe the file has data for.

    Raises:
        ValueError: an unknown probe name.
        TraceFileError: a named probe the file has no data for.
    """
    if probe not in ("both", "relaxation", "slip"):
        raise ValueError(f"probe must be 'both', 'relaxation' or 'slip', got {probe!r}")
    if probe == "both":
        return traces.probes
    if probe not in traces.probes:
        has = " and ".join(traces.probes)
        raise TraceFileError(traces.path, f"no {probe} data (the file has {has} data)")
    return (probe,)


def estimate_recorded(
    traces: RecordedTraces, *, method: str = "full", probe: str = "both",
    contact_angle: float | None = None, mu_reading: MuReading = "slipping"
) -> RecordedEstimates:
    """Run the estimators on recorded traces: the one place that picks them.  The clamp as
    the study's simulated probes run it (the full fit with the simulator's clamp weight, or
    the three-step method); the slide by ``mu_reading``: "slipping", mu as the simulated
    probes read it (:func:`read_recorded_mu`; where the file marks no slide, the study's
    estimator, with a note, never reliable), or "study", the study's friction estimator.
    An estimator's failure is kept in ``failures``, not raised.  ``contact_angle`` [rad],
    where known, is the full fit's first-contact angle.

    Raises:
        ValueError: an unknown method, probe name or mu reading, or a contact angle with the
            three-step method (which reads it off the trace).
        TraceFileError: ``probe`` names a probe the file has no data for.
    """
    if method not in ("full", "three-step"):
        raise ValueError(f"method must be 'full' or 'three-step', got {method!r}")
    if mu_reading not in MU_READINGS:
        raise ValueError(f"mu_reading must be one of {MU_READINGS}, got {mu_reading!r}")
    if contact_angle is not None and method != "full":
        raise ValueError("a known contact angle is for the full fit (--method full); the "
                         "three-step method reads it off the trace")
    run = probes_to_run(traces, probe)
    out = RecordedEstimates()
    caught = (EstimationError, ArithmeticError, np.linalg.LinAlgError)
    if "relaxation" in run:
        t, theta, m, geometry = traces.relaxation_inputs()
        t0 = time.perf_counter()
        try:
            if method == "full":
                out.relaxation = estimate_full_fit(
                    t, theta, m, geometry, clamp_weight=SIM_CLAMP_WEIGHT, theta_1=contact_angle)
            else:
                out.relaxation = estimate_three_step(t, theta, m, geometry)
        except caught as exc:
            out.failures["relaxation"] = f"{type(exc).__name__}: {exc}"
        out.fit_time = time.perf_counter() - t0
    if "slip" in run:
        slide = slide_samples(traces) if mu_reading == "slipping" else None
        fallback = mu_reading == "slipping" and slide is None
        if fallback:
            out.notes.append("the file marks no slide (no phase 'slide' or slide_start): mu "
                             "read by the study's plateau, which finds the slide itself; not "
                             "reliable")
        try:
            if slide is not None:
                out.friction = read_recorded_mu(traces, slide)
            else:
                out.friction = estimate_friction(*traces.slip_inputs(),
                                                 slide_start=traces.slide_start)
                out.friction.reliable &= not fallback
        except caught as exc:
            out.failures["slip"] = f"{type(exc).__name__}: {exc}"
    return out


def slide_samples(traces: RecordedTraces) -> np.ndarray | None:
    """Which samples of a recorded run are its slide: those the phase column marks
    ``slide``, from ``slide_start`` on (a log may go on after the slide: a release, a
    lift); without such a column, every sample from ``slide_start`` on; None where the file
    marks no slide."""
    marked = traces.in_phase("slide")
    if traces.slide_start is not None:
        after = traces.t >= traces.slide_start
        marked = after if marked is None else marked & after
    return marked if marked is not None and marked.any() else None


def settle_samples(traces: RecordedTraces) -> np.ndarray | None:
    """The samples before the blades touch the piece, whose force readings are the sensor's
    noise alone: those the phase column marks ``settle`` and those before ``clamp_start``;
    None where the file marks neither."""
    marked = traces.in_phase("settle")
    if traces.clamp_start is not None:
        before = traces.t < traces.clamp_start
        marked = before if marked is None else marked | before
    return marked


def read_recorded_mu(traces: RecordedTraces, slide: np.ndarray) -> SlipReading:
    """mu from a recorded slide as the simulated slip probe reads its own
    (:func:`estimators.slip_level.read_mu`, ``per_blade_simex``): each half-spoon's force ratio at
    the level it slips at, the lower of the two, less the bias the sensor's noise puts into
    it (the noise read from :func:`settle_samples`; without them, uncorrected, with a
    warning).  Raises :class:`estimators.EstimationError` when the slide gives no mu."""
    t, *forces = traces.slip_inputs()
    named = dict(zip(SLIP_FORCES, forces, strict=True))
    diagnostics: dict[str, float] = {}
    mu, warns, interval = read_mu(t, named, slide, settle_samples(traces), "per_blade_simex",
                                  diagnostics)
    return SlipReading(mu, interval, within_half_width(mu, interval), warns, diagnostics)


def to_probe_estimate(traces: RecordedTraces, got: RecordedEstimates) -> ProbeEstimate:
    """The report of ``estimate`` (true values unknown: NaN) from :func:`estimate_recorded`."""
    out = ProbeEstimate(true=dict.fromkeys(NAMES, math.nan),
                        estimate=dict.fromkeys(NAMES, math.nan), interval={})
    for probe, error in got.failures.items():
        out.reliable = False
        out.warnings.append(f"{probe} probe: {error}")
    est = got.relaxation
    if est is not None:
        out.add_relaxation(est, got.fit_time)
        out.details["relaxation"]["n_samples"] = int(traces.relaxation_inputs()[0].size)
    if isinstance(got.friction, SlipReading):
        fr = got.friction
        out.estimate["mu"], out.interval["mu"] = fr.mu, fr.interval
        out.reliable &= fr.reliable
        out.warnings += [f"slip probe: {w}" for w in fr.warnings]
        out.details["slip"] = {"reading": "slipping", "diagnostics": fr.diagnostics}
    elif got.friction is not None:
        out.add_friction(got.friction)
        out.details["slip"]["reading"] = "study"
    out.warnings += [f"slip probe: {n}" for n in got.notes]
    return out


def check_trace_options(args: argparse.Namespace) -> None:
    """Refuse ``--L``/``--theta-0``/``--contact-angle``/``--mu-reading`` without
    ``--traces``, simulation options with it, and ``--contact-angle`` with ``--method
    three-step``."""
    if args.traces is None:
        given = [o for o, v in (("--L", args.L), ("--theta-0", args.theta_0),
                                ("--contact-angle", args.contact_angle),
                                ("--mu-reading", args.mu_reading)) if v is not None]
        raise UsageError(f"{PROG}: {' and '.join(given)} "
                         f"{'needs' if len(given) == 1 else 'need'} --traces FILE (a simulated "
                         "run knows its geometry and reads mu as its probes do)")
    given = list(dict.fromkeys(args.simulation_options))
    if given:
        raise UsageError(f"{PROG}: {', '.join(given)} cannot be used with --traces (they set "
                         "the simulated run; a recorded one is estimated as it is)")
    if args.contact_angle is not None and args.method != "full":
        raise UsageError(f"{PROG}: --contact-angle is for the full fit (--method full); the "
                         "three-step method reads the contact angle off the trace")


def _check_mu_reading(reading: str | None, traces: RecordedTraces, probe: str) -> None:
    """Refuse a ``--mu-reading`` that no slide of the run would use."""
    if reading is not None and "slip" not in probes_to_run(traces, probe):
        raise UsageError(f"{PROG}: --mu-reading is for a slip trace, and none is estimated "
                         "here")


def _check_contact_angle(angle: float | None, traces: RecordedTraces, probe: str) -> None:
    """Refuse a known contact angle that no relaxation trace can use: negative, or not below
    the largest hinge angle the trace reached (no squeeze past it)."""
    if angle is None:
        return
    if "relaxation" not in probes_to_run(traces, probe):
        raise UsageError(f"{PROG}: --contact-angle is for a relaxation trace, and none is "
                         "estimated here")
    top = float(np.max(traces.relaxation_inputs()[1]))
    if not 0.0 <= angle < top:
        raise UsageError(f"{PROG}: --contact-angle {angle:g} rad must be in [0, {top:g}) rad, "
                         "below the largest hinge angle of the relaxation trace")


def cmd_estimate_traces(args: argparse.Namespace) -> int:
    """``food-fetch estimate --traces FILE``: load, estimate, report (and ``--json``)."""
    check_trace_options(args)
    require_distinct(PROG, {"--traces": args.traces, "--json": args.json})
    try:
        traces = load_traces(args.traces, L=args.L, theta_0=args.theta_0)
        _check_contact_angle(args.contact_angle, traces, args.probe)
        _check_mu_reading(args.mu_reading, traces, args.probe)
        got = estimate_recorded(traces, method=args.method, probe=args.probe,
                                contact_angle=args.contact_angle,
                                mu_reading=args.mu_reading or "slipping")
    except TraceFileError as exc:
        raise UsageError(f"{PROG}: {exc}") from None
    result = to_probe_estimate(traces, got)
    result.details["settings"] = {
        "traces": traces.path, "method": args.method, "probe": args.probe,
        "mu_reading": args.mu_reading or "slipping",
        "clamp_weight": SIM_CLAMP_WEIGHT, "contact_angle": args.contact_angle,
        "n_samples": int(traces.t.size),
        "source": dict(traces.source),
    }
    geom = traces.geometry
    geometry = (f"L {geom.L:g} m ({traces.source['L']}), theta_0 {geom.theta_0:g} rad "
                f"({traces.source['theta_0']})" if geom is not None else "no geometry")
    read = {"slipping": "mu at each half-spoon's slipping level",
            "study": "mu by the study's plateau"}
    slip = result.details.get("slip", {}).get("reading")
    print(f"recorded traces {traces.path}: {traces.t.size} samples, "
          f"{' and '.join(probes_to_run(traces, args.probe))} data; {geometry}"
          + (f"; {read[slip]}" if slip in read else ""))
    print_report(result)
    if args.json is not None:
        write_json(args.json, result.to_dict())
        print(f"wrote {args.json}")
    return 0
