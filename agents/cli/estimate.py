"""``food-fetch estimate``: run the two probes on one food and estimate what they measure.

The relaxation probe (clamp to ``theta_d`` at ``omega``, hold) feeds the viscoelastic estimator
(:func:`estimators.estimate_full_fit` or the study's :func:`estimators.estimate_three_step`) with
the measured hinge angle and the moment averaged over both half-spoons; the induced-slip probe
feeds :func:`estimators.estimate_friction` with both half-spoons' contact forces.  The result is
printed (true against estimated, with errors and 95 % intervals) and optionally written as JSON.

The truth.  ``g1``, ``tau1`` and ``mu`` are the material's, compared exactly.  ``K1, K2, B`` are
not material constants: they are the SLS springs of *this piece in this clamp*.  They are defined
by a third, purely elastic run (the same piece and clamp with ``g1 = 0``): its relaxed moment
through eq. 7 gives the clamp's elastic stiffness ``K_el`` (N/m), the instantaneous stiffness
``K1 + K2`` a linear viscoelastic piece of modulus ``E_0`` has here; then ``K2 = g1 K_el``,
``K1 = K_el - K2`` and ``B = tau1 K2``.  The nominal ``2 E_0 A / l`` is reported beside it.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from agents.cli.common import (
    UsageError,
    add_food_options,
    finite,
    make_material,
    positive_int,
    writable,
    write_json,
)
from fetch_env.clipping import message as clip_message
from fetch_env.clipping import record as clip_record
from fetch_env.probes import ProbeRuns, nominal_stiffness
from fetch_env.study_probes import (
    RELAXATION_DEFAULTS,
    SIM_CLAMP_WEIGHT,
    SLIP_DEFAULTS,
    run_relaxation_probe,
    run_slip_probe,
    study_elastic_stiffness,
)

HELP = "run the relaxation and slip probes on a food and estimate K1/K2/B, g1, tau1, mu"
DESCRIPTION = ("Run the moment-relaxation probe and the induced-slip probe on one food "
               "piece in the simulator, estimate K1, K2, B (hence g1, tau1) and mu from the "
               "simulated sensors, and print them against the truth with errors and 95 % "
               "intervals.")

NAMES = ("K1", "K2", "B", "g1", "tau1", "mu")
# Where --theta-d is not given, each probe's angle adapts to the piece: its default above,
# kept within the angles that squeeze the piece by these shares of its half-width past the
# first contact the faces reach its rest surface at (fetch_env.probes.probe_angle).  The
# study's 15 mm cube keeps the study's 0.0244 rad; a 22 mm sphere, which the faces first
# touch at ~0.04 rad, is squeezed instead of missed, and a large stiff cube is not driven
# into the motor's stall.
ADAPTIVE_STRAIN = {"relaxation": (0.03, 0.12), "slip": (0.05, 0.25)}


@dataclass
class ProbeEstimate:
    """What one ``estimate`` run measured (SI units; NaN where a probe was skipped/failed)."""

    true: dict[str, float]
    estimate: dict[str, float]
    interval: dict[str, tuple[float, float]]
    r2_clamp: float = math.nan
    r2_hold: float = math.nan
    reliable: bool = True
    warnings: list[str] = field(default_factory=list)
    details: dict[str, Any] = field(default_factory=dict)
    clipped: list[dict[str, Any]] = field(default_factory=list)  # fetch_env.clipping records

    def errors(self) -> dict[str, float]:
        """Relative error (estimate / true - 1) per name, NaN where undefined."""
        out = {}
        for k in NAMES:
            tv, ev = self.true.get(k, math.nan), self.estimate.get(k, math.nan)
            out[k] = ev / tv - 1.0 if np.isfinite(tv) and tv != 0 and np.isfinite(ev) else math.nan
        return out

    def add_relaxation(self, est: Any, fit_time: float) -> None:
        """Take K1, K2, B, g1, tau1, their intervals, R^2 and warnings from a viscoelastic
        estimate, and its fit facts into ``details["relaxation"]``."""
        self.estimate.update(K1=est.K1, K2=est.K2, B=est.B, g1=est.g1, tau1=est.tau1)
        self.interval.update({k: v for k, v in est.intervals.items() if k in NAMES})
        self.r2_clamp, self.r2_hold = est.r2_clamp, est.r2_hold
        self.reliable &= est.reliable
        self.warnings += [f"relaxation probe: {w}" for w in est.warnings]
        self.details.setdefault("relaxation", {}).update(
            theta_1=est.theta_1, M_peak=est.M_peak, M_inf=est.M_inf, fit_time=fit_time,
            method=est.method)

    def add_friction(self, fe: Any) -> None:
        """Take mu, its interval and warnings from a friction estimate, and its fit facts
        into ``details["slip"]``."""
        self.estimate["mu"] = fe.mu
        self.interval["mu"] = fe.interval
        self.reliable &= fe.reliable
        self.warnings += [f"slip probe: {w}" for w in fe.warnings]
        self.details.setdefault("slip", {}).update(
            window=list(fe.window), mu_left=fe.mu_left, mu_right=fe.mu_right,
            n_samples=fe.n_samples)

    def to_dict(self) -> dict[str, Any]:
        def num(v: float) -> float | None:
            return float(v) if np.isfinite(v) else None

        return {
            "true": {k: num(v) for k, v in self.true.items()},
            "estimate": {k: num(v) for k, v in self.estimate.items()},
            "error": {k: num(v) for k, v in self.errors().items()},
            "interval": {k: [num(lo), num(hi)] for k, (lo, hi) in self.interval.items()},
            "r2_clamp": num(self.r2_clamp),
            "r2_hold": num(self.r2_hold),
            "reliable": self.reliable,
            "warnings": self.warnings,
            "details": self.details,
            "clipped": self.clipped,
        }


def _check(args: argparse.Namespace) -> None:
    if getattr(args, "lift_speed", None) is not None:
        # Neither probe lifts: accepting it silently would suggest it changed something.
        raise UsageError(
            f"food-fetch estimate: --lift-speed {args.lift_speed:g} has no effect here "
            "(neither probe lifts; it is a simulate --experiment fetch option)"
        )
    if not 0.0 <= args.noise <= 0.5:
        raise UsageError(f"food-fetch estimate: --noise must be in [0, 0.5], got {args.noise:g}")
    if not 0.0 < args.slide_time <= 120.0:
        raise UsageError(
            f"food-fetch estimate: --slide-time (slide_time) must be in (0, 120] s, "
            f"got {args.slide_time:g}"
        )
    if not 0.0 < args.clamp_weight <= 1e6:
        raise UsageError(
            f"food-fetch estimate: --clamp-weight must be in (0, 1e6], got {args.clamp_weight:g}"
        )


def adaptive_angle(pieces: tuple[Any, ...], probe: str, default: float) -> float:
    """``default`` kept within the angles that squeeze the piece by ``ADAPTIVE_STRAIN``."""
    from fetch_env.controller import FetchSimulator
    from fetch_env.probes import probe_angle

    sim = FetchSimulator(pieces)
    lo, hi = (probe_angle(sim, strain, probe) for strain in ADAPTIVE_STRAIN[probe])
    return float(min(max(default, lo), hi))


def probe_actions(args: argparse.Namespace, pieces: tuple[Any, ...]) -> dict[str, Any]:
    """The ``FetchAction`` of every probe ``--probe`` runs, built (hence validated, with
    simulate's messages) before any simulation; an omitted ``--theta-d`` adapts to the
    piece (:func:`adaptive_angle`).

    An explicit ``--theta-d/--omega/--hold`` sets the probe of ``--probe relaxation|slip``,
    and only the relaxation probe under ``--probe both``: the probes want very different
    settings (a 6 s relaxation hold before the slide left the slip probe with no steady slip,
    measured), so one value for both would be a trap.  An omitted one takes that probe's
    default."""
    from fetch_env.controller import FetchAction

    out = {}
    for probe, defaults in (("relaxation", RELAXATION_DEFAULTS), ("slip", SLIP_DEFAULTS)):
        if args.probe not in ("both", probe):
            continue
        given = probe == "relaxation" or args.probe == "slip"
        kw = {k: getattr(args, k) if given and getattr(args, k) is not None else defaults[k]
              for k in ("theta_d", "omega", "hold")}
        if not (given and args.theta_d is not None):
            kw["theta_d"] = adaptive_angle(pieces, probe, defaults["theta_d"])
        if probe == "slip":
            kw["slide_time"] = args.slide_time
        out[probe] = FetchAction(**kw)
    return out


STUDY_OPTIONS = ("--theta-d", "--omega", "--hold", "--clamp-weight", "--slide-time")
# the presets of fetch_env.probes that --probes offers besides the study's fixed clamp
ADAPTIVE_PROBES = ("precise", "repeated", "measure")


def which_probes(args: argparse.Namespace) -> str:
    """``--probes``, or where it is omitted: "study" when a study-probe option is given
    (``STUDY_OPTIONS`` or ``--method three-step``), else "precise"."""
    given = [o for o in STUDY_OPTIONS if o in getattr(args, "simulation_options", ())]
    if args.probes in ADAPTIVE_PROBES and (given or args.method != "full"):
        what = ", ".join(given) or f"--method {args.method}"
        raise UsageError(f"food-fetch estimate: {what} sets the study's probes; it has no "
                         f"effect with --probes {args.probes} (give --probes study)")
    if args.probes is not None:
        return str(args.probes)
    return "study" if given or args.method != "full" else "precise"



def run_measure(args: argparse.Namespace, pieces: tuple[Any, ...], material: Any,
                preset: str = "precise") -> ProbeEstimate:
    """The shared probes of ``fetch_env.probes``, ``preset``'s settings (adaptive angles,
    20 s time-scaled holds, calibrated, intervals with model error), held to the
    elastic-twin truth."""
    from fetch_env.errors import SimulationDivergedError
    from fetch_env.probes import (
        PROBE_CALIBRATIONS,
        PROBE_PRESETS,
        run_probes,
        simulate_probes,
        true_parameters_exact,
    )

    config = PROBE_PRESETS[preset]
    calibration = PROBE_CALIBRATIONS.get(preset)
    start = time.perf_counter()
    # On several workers the elastic twin runs in the probes' pool, beside their clamps
    # and slides; on one, after them, as run_probes would.
    runs = (simulate_probes(pieces, config, workers=args.workers, truth=True)
            if args.workers > 1 else None)
    res = run_probes(pieces, config, noise=args.noise, seed=args.seed,
                     calibration=calibration, workers=args.workers, runs=runs)
    keep = {"both": NAMES, "relaxation": NAMES[:5], "slip": ("mu",)}[args.probe]
    estimate = {k: res.estimates[k] if k in keep else math.nan for k in NAMES}
    interval = {k: res.intervals.get(k, (math.nan, math.nan)) for k in keep}
    out = ProbeEstimate(true=dict.fromkeys(NAMES, math.nan), estimate=estimate,
                        interval=interval, reliable=res.reliable, warnings=list(res.warnings))
    try:
        truth = _twin_truth(runs) if runs is not None else true_parameters_exact(pieces[0],
                                                                                  config)
    except SimulationDivergedError as exc:
        out.warnings.append(f"true K1, K2, B not computed: the elastic twin diverged: {exc}")
        truth = {"K1": math.nan, "K2": math.nan, "B": math.nan, "g1": material.g1,
                 "tau1": material.tau1, "mu": material.mu}
    if not truth["K1"] + truth["K2"] > 0:
        out.warnings.append("true K1, K2, B not computed: the elastic twin gave no moment")
        truth.update(K1=math.nan, K2=math.nan, B=math.nan)
    out.true.update({k: truth[k] for k in keep})
    out.details["settings"] = {
        "probes": preset, "noise": args.noise, "seed": args.seed, "probe": args.probe,
        "config": dataclasses.asdict(config),
        "calibration": None if calibration is None else (
            f"{calibration.form}, fitted on {calibration.n_foods} reference foods")}
    out.details["probes"] = {k: v for k, v in res.details.items() if k != "uncalibrated"}
    out.details["uncalibrated"] = res.details.get("uncalibrated")
    out.details["wall_time"] = time.perf_counter() - start  # the probes, fits and twin
    return out


def _twin_truth(runs: ProbeRuns) -> dict[str, float]:
    """The elastic twin's truth that ``simulate_probes(truth=True)`` ran, or the error it
    raised, raised again here."""
    if isinstance(runs.truth, BaseException):
        raise runs.truth
    assert runs.truth is not None  # run_measure asks simulate_probes for the twin
    return dict(runs.truth)


def probe_clips(args: argparse.Namespace, pieces: tuple[Any, ...], probes: str,
                actions: dict[str, Any]) -> list[dict[str, Any]]:
    """What the probes change of the given values (``fetch_env.clipping``): the modulus
    capped at each probe's physics step, and a ``--theta-d`` beyond the end stop."""
    from fetch_env.controller import CLOSED_MARGIN, FetchSimulator
    from fetch_env.probes import PROBE_PRESETS
    from fetch_env.scene import BASE_TIMESTEP, young_caps

    config = PROBE_PRESETS.get(probes, PROBE_PRESETS["measure"])
    steps = ({"relaxation": config.relaxation_timestep or BASE_TIMESTEP,
              "slip": config.slip_timestep} if probes in ADAPTIVE_PROBES
             else {"relaxation": BASE_TIMESTEP, "slip": BASE_TIMESTEP})
    out: list[dict[str, Any]] = []
    for probe in ("relaxation", "slip"):
        if args.probe in ("both", probe):
            out += young_caps(pieces, steps[probe], where=f" in the {probe} probe")
    for probe, action in actions.items():
        closed = FetchSimulator(pieces).scene_for(probe).pose.theta_closed
        if args.theta_d is not None and action.theta_d > closed - CLOSED_MARGIN:
            out.append(clip_record(
                "end_stop", f"theta_d ({probe} probe)", action.theta_d, closed - CLOSED_MARGIN,
                f"the controller's end stop, {CLOSED_MARGIN:g} rad before the half-spoons' "
                f"tips meet at {closed:.4f} rad"))
    return out


def run_estimate(args: argparse.Namespace) -> ProbeEstimate:
    from fetch_env.clipping import reported_elsewhere
    from fetch_env.layouts import Piece

    _check(args)
    material = make_material(args)
    pieces = (Piece(args.shape, args.size, material),)
    probes = which_probes(args)
    if args.workers > 1 and probes not in ADAPTIVE_PROBES:
        raise UsageError(f"food-fetch estimate: --workers {args.workers} applies to the "
                         f"{', '.join(ADAPTIVE_PROBES)} probes, not to --probes {probes}")
    with reported_elsewhere():  # in the text and the JSON's "clipped" instead
        if probes in ADAPTIVE_PROBES:
            out = run_measure(args, pieces, material, probes)
            out.clipped = probe_clips(args, pieces, probes, {})
            return out
        out, actions = _run_study(args, pieces, material)
        out.clipped = probe_clips(args, pieces, probes, actions)
    return out


def _run_study(args: argparse.Namespace, pieces: tuple[Any, ...], material: Any
               ) -> tuple[ProbeEstimate, dict[str, Any]]:
    """The study's fixed-clamp probes (``--probes study``), held to the elastic twin; and
    the ``FetchAction`` each probe ran."""
    actions = probe_actions(args, pieces)  # every input is valid past here
    true = {k: math.nan for k in NAMES}
    true.update(g1=material.g1, tau1=material.tau1, mu=material.mu)
    out = ProbeEstimate(true=true, estimate={k: math.nan for k in NAMES}, interval={})
    out.details["settings"] = {
        "method": args.method,
        "noise": args.noise,
        "seed": args.seed,
        "clamp_weight": args.clamp_weight,
        "probe": args.probe,
    }
    if "relaxation" in actions:
        _study_relaxation(args, pieces, actions["relaxation"], out)
    if "slip" in actions:
        _study_slip(args, pieces, actions["slip"], out)
    return out, actions


def _record_probe(out: ProbeEstimate, name: str, run: dict[str, Any]) -> Any:
    """Put a study probe's run facts into ``out.details[name]``; its estimate, or None with
    the reason in the warnings and ``reliable`` False."""
    out.details[name] = {
        "action": run["action"].to_dict(),
        "wall_sim": run["wall_sim"],
        "max_log_strain": run["max_log_strain"],
    }
    if run["estimate"] is None:
        out.reliable = False
        out.warnings.append(f"{name} probe: {run['error']}")
    return run["estimate"]


def _study_relaxation(args: argparse.Namespace, pieces: tuple[Any, ...], a: Any,
                      out: ProbeEstimate) -> None:
    """The study's relaxation probe into ``out``: K1, K2, B, g1, tau1, their intervals and
    fit facts, and the elastic-twin truth for K1, K2, B."""
    r = run_relaxation_probe(pieces, a.theta_d, a.omega, a.hold, args.method, args.noise,
                             args.seed, args.clamp_weight)
    est = _record_probe(out, "relaxation", r)
    if est is not None:
        out.add_relaxation(est, r["wall_fit"])
    material = pieces[0].material
    if np.isfinite(material.g1) and material.g1 > 0:
        _truth_k(pieces, r["action"], material, out.true, out)


def _study_slip(args: argparse.Namespace, pieces: tuple[Any, ...], a: Any,
                out: ProbeEstimate) -> None:
    """The study's induced-slip probe into ``out``: mu, its interval and the fit's facts."""
    s = run_slip_probe(pieces, a.theta_d, a.omega, a.hold, a.slide_time, noise=args.noise,
                       seed=args.seed)
    fe = _record_probe(out, "slip", s)
    if fe is not None:
        out.add_friction(fe)


def _truth_k(pieces: tuple[Any, ...], action: Any, material: Any, true: dict[str, float],
             out: ProbeEstimate) -> None:
    """Fill the true K1, K2, B from the elastic twin (see the module docstring); where the
    twin gives no moment, say why and leave them NaN."""
    from estimators import EstimationError

    try:
        k_el, info = study_elastic_stiffness(pieces, action)
    except (EstimationError, ArithmeticError) as exc:
        out.warnings.append(f"true K1, K2, B not computed: the elastic twin run gave {exc}")
        return
    k2 = material.g1 * k_el
    true.update(K1=k_el - k2, K2=k2, B=material.tau1 * k2)
    out.details["truth_K"] = {
        "K_elastic": k_el,
        "K_nominal": nominal_stiffness(pieces[0]),
        **info,
        "definition": "K1+K2 = eq. 7 stiffness of a g1=0 run",
    }


def _fmt(v: float) -> str:
    return f"{v:.6g}" if np.isfinite(v) else "-"


def print_report(r: ProbeEstimate) -> None:
    errs = r.errors()
    units = {"K1": "N/m", "K2": "N/m", "B": "N s/m", "g1": "", "tau1": "s", "mu": ""}
    print(f"{'name':<6}{'true':>12} {'estimate':>12} {'error':>11}   95 % interval")
    for k in NAMES:
        lo, hi = r.interval.get(k, (math.nan, math.nan))
        err = f"{100 * errs[k]:+.3f} %" if np.isfinite(errs[k]) else "-"
        iv = f"[{_fmt(lo)}, {_fmt(hi)}]" if np.isfinite(lo) else "-"
        print(f"{k:<6}{_fmt(r.true[k]):>12} {_fmt(r.estimate[k]):>12} {err:>11}   {iv} "
              f"{units[k]}")
    print(f"R^2 clamp {_fmt(r.r2_clamp)}, hold {_fmt(r.r2_hold)}; reliable: {r.reliable}")
    settings = r.details.get("settings", {})
    if "calibration" in settings:
        config = settings["config"]
        clamps, slides = config["relaxation_repeats"], config.get("slip_repeats", 1)
        print(f"probes: {settings['probes']} ({clamps} relaxation "
              f"clamp{'s' if clamps > 1 else ''}, {slides} slide{'s' if slides > 1 else ''}, "
              f"{config['contact_angle']} contact angle); "
              f"calibration: {settings['calibration'] or 'none'}")
    if "truth_K" in r.details:
        d = r.details["truth_K"]
        print(
            f"true K1+K2 = {d['K_elastic']:.6g} N/m: eq. 7 on a purely elastic run "
            f"(nominal 2 E A / l = {d['K_nominal']:.6g} N/m)"
        )
    for w in r.warnings:
        print(f"warning: {w}")
    for rec in r.clipped:
        print(f"simulated {clip_message(rec)}")


def cmd_estimate(args: argparse.Namespace) -> int:
    if any(getattr(args, k, None) is not None
           for k in ("traces", "L", "theta_0", "contact_angle", "mu_reading")):
        from agents.cli.traces import cmd_estimate_traces  # recorded, not simulated

        return cmd_estimate_traces(args)
    result = run_estimate(args)
    if all(not math.isfinite(v) for v in result.estimate.values()):
        reasons = "; ".join(result.warnings) or "no probe gave an estimate"
        raise UsageError(f"food-fetch estimate: nothing could be estimated: {reasons}")
    print_report(result)
    if args.json is not None:
        write_json(args.json, result.to_dict())
        print(f"wrote {args.json}")
    return 0


def _clamp_help(p: argparse.ArgumentParser) -> None:
    """The clamp options' help with the probes' own defaults; --lift-speed hidden."""
    # add_food_options documents simulate's defaults; estimate's probes have their own (from
    # the dicts above, so the help cannot disagree with the code).
    r, s = RELAXATION_DEFAULTS, SLIP_DEFAULTS
    clamp_help = {
        "--theta-d": "preset angular displacement from the open pose [rad] "
        f"(default: {r['theta_d']:g} for the relaxation probe, {s['theta_d']:g} for slip, "
        "each kept within the angles that squeeze the piece by 3-12 %% (slip 5-25 %%) of its "
        "half-width past first contact, so every size and shape is touched)",
        "--omega": "clamping angular velocity [rad/s] "
        f"(default: {r['omega']:g} for the relaxation probe, {s['omega']:g} for slip)",
        "--hold": "hold at theta_d [s] "
        f"(default: {r['hold']:g} for the relaxation probe, {s['hold']:g} for slip)",
    }
    for option, text in clamp_help.items():
        p._option_string_actions[option].help = (
            text + "; a value given applies to --probe relaxation or slip, and to the "
            "relaxation probe only under --probe both")
    # Neither probe lifts: hide --lift-speed and reject it when given (see _check).
    p._option_string_actions["--lift-speed"].help = argparse.SUPPRESS
    p.set_defaults(lift_speed=None)


def add_options(p: argparse.ArgumentParser) -> None:
    """The options of ``food-fetch estimate``."""
    from agents.cli.simulate import help_caps

    add_food_options(p)
    _clamp_help(p)
    help_caps(p)
    p.add_argument(
        "--probes",
        choices=(*ADAPTIVE_PROBES, "study"),
        default=None,
        help="precise: probes made for any food (the clamp angle adapts to the piece, seven "
        "20 s time-scaled relaxation clamps at nearby squeezes and the medians of g1 and "
        "tau1, K1, K2, B at the depth camera's contact angle, a 1 ms step, nearly rigid "
        "friction and the blades' contact stiffened so that the held moment relaxes as the "
        "food does, a calibration fitted on reference foods, 95 %% "
        "intervals that include model error; docs/estimator_validation.md; about 5 s a "
        "food); repeated: the same at the environments' 5 ms step and contact, a fifth of "
        "the time; measure: repeated with one clamp and the fitted contact angle (the "
        "probes of FoodFetch-Row-v2); study: the study's fixed clamp (--theta-d, --omega, "
        "--hold, --method, --clamp-weight, --slide-time). Default: study where one of those "
        "is given, else precise",
    )
    p.add_argument(
        "--method",
        choices=("full", "three-step"),
        default="full",
        help="viscoelastic estimator: one least-squares fit of the whole trace "
        "(default) or the study's three-step method",
    )
    p.add_argument(
        "--noise",
        type=finite(),
        default=0.0,
        metavar="FRACTION",
        help="white sensor noise added to the traces, as a fraction of the peak "
        "moment (and of the peak contact force) (default: 0)",
    )
    p.add_argument(
        "--clamp-weight",
        type=finite(),
        default=SIM_CLAMP_WEIGHT,
        metavar="W",
        help="full fit: weight of clamp-phase samples relative to hold samples "
        f"(default: {SIM_CLAMP_WEIGHT}; 1 is ordinary least squares)",
    )
    p.add_argument(
        "--probe",
        choices=("both", "relaxation", "slip"),
        default="both",
        help="which probes to run (default: both)",
    )
    p.add_argument(
        "--slide-time",
        type=finite(),
        default=SLIP_DEFAULTS["slide_time"],
        metavar="S",
        help="duration of the induced slip [s] (default: 10)",
    )
    p.add_argument(
        "--workers",
        type=positive_int,
        default=1,
        metavar="N",
        help="run the probes' simulations (the precise probes' seven clamps and five "
        "slides, and the elastic twin the estimates are held to) on N processes at once: "
        "the same numbers as with 1, sooner where cores are free; the JSON's CPU times are "
        "then this process's only (default: 1)",
    )
    p.add_argument(
        "--json",
        type=writable,
        default=None,
        metavar="FILE",
        help="write true, estimate, error, interval, r2_clamp, r2_hold as JSON",
    )
    from agents.cli.traces import add_traces_options

    add_traces_options(p)  # --traces FILE [--L] [--theta-0]; last: it marks the options above
