"""``food-fetch reproduce EXPERIMENT``: rerun one of the study's virtual experiments here and
write its tables (CSV and markdown), texts and figures (PNG) to a folder, the study's numbers
beside this project's.

The experiments themselves live in :mod:`agents.study` and return what they produced; this
module holds their command-line options, checks every option before ``--out`` is created (a
rejected call leaves nothing behind) and writes each file through a temporary file and a
rename.
"""

from __future__ import annotations

import argparse
import math
import os
import shutil
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from agents.cli.common import UsageError, finite, out_dir, require_extra, seed, write_text
from agents.study import fetch_rate, friction, viscoelastic
from agents.study.report import StudyOptionError, StudyResult

HELP = "rerun one of the study's virtual experiments, writing tables and figures"
DESCRIPTION = ("Rerun one of the study's virtual experiments in the simulator and write "
               "its tables (CSV, markdown) and figures (PNG) to --out, with the study's reported "
               "numbers (docs/study.md) beside this project's.")

PREFIX = "food-fetch reproduce"


def parse_list(text: str, allowed: tuple[str, ...] | None, what: str) -> list[str]:
    """A comma-separated option's items (``allowed`` names the valid ones, if any)."""
    items = [s.strip() for s in text.split(",")]
    if not any(items):
        raise UsageError(f"{PREFIX}: --{what} is empty")
    if not all(items):  # "0.1,,0.2": a value lost in typing, not to be skipped unsaid
        raise UsageError(f"{PREFIX}: --{what} {text!r} has an empty item")
    if allowed is not None:
        bad = [s for s in items if s not in allowed]
        if bad:
            raise UsageError(f"{PREFIX}: unknown {what} {bad[0]!r}; choose from "
                             f"{','.join(allowed)}")
    return items


def parse_numbers(text: str, what: str) -> list[float]:
    """A comma-separated option's numbers (finite; their ranges are the experiment's)."""
    out = []
    for s in parse_list(text, None, what):
        try:
            v = float(s)
        except ValueError:
            raise UsageError(f"{PREFIX}: --{what}: not a number: {s!r}") from None
        if not math.isfinite(v):
            raise UsageError(f"{PREFIX}: --{what}: not a finite number: {s!r}")
        out.append(v)
    return out


def _friction_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("--shapes", default=",".join(friction.SHAPES), metavar="LIST",
                   help="comma-separated shapes (default: cube,ellipsoid,sphere)")
    p.add_argument("--mus", default=",".join(f"{m:g}" for m in friction.MUS), metavar="LIST",
                   help="comma-separated true mu values (default: 0.1,0.2,0.3,0.5)")
    p.add_argument("--slide-time", type=finite(), default=10.0, metavar="S",
                   help="duration of the 5 mm slide [s] (default: 10, the study's)")
    p.add_argument("--noise", type=finite(), default=0.0, metavar="FRACTION",
                   help="white noise on the contact forces, fraction of their peak (default: 0)")


def _friction_kwargs(args: argparse.Namespace) -> dict[str, Any]:
    return {"shapes": parse_list(args.shapes, friction.SHAPES, "shapes"),
            "mus": parse_numbers(args.mus, "mus"), "slide_time": args.slide_time,
            "noise": args.noise, "seed": args.seed}


def _viscoelastic_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("--omegas", default=",".join(f"{w:g}" for w in viscoelastic.OMEGAS),
                   metavar="LIST",
                   help="comma-separated clamping velocities [rad/s] (default: 0.01,...,0.04)")
    p.add_argument("--hold", type=finite(), default=25.0, metavar="S",
                   help="hold at theta_d [s] (default: 25)")
    p.add_argument("--noise", type=finite(), default=0.0, metavar="FRACTION",
                   help="white noise on the moment, fraction of its peak (default: 0)")
    p.add_argument("--clamp-weight", type=finite(), default=0.3, metavar="W",
                   help="full fit: weight of clamp samples relative to hold samples (default: "
                   "0.3, as food-fetch estimate; 1 is ordinary least squares)")


def _viscoelastic_kwargs(args: argparse.Namespace) -> dict[str, Any]:
    return {"omegas": parse_numbers(args.omegas, "omegas"), "hold": args.hold,
            "noise": args.noise, "clamp_weight": args.clamp_weight, "seed": args.seed}


def _fetch_rate_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("--quick", action="store_true",
                   help="one diced mix instead of three (about a minute less)")
    p.add_argument("--no-figures", action="store_true", help="skip the PNG figures")


def _fetch_rate_kwargs(args: argparse.Namespace) -> dict[str, Any]:
    return {"quick": args.quick, "seed": args.seed, "with_figures": not args.no_figures}


@dataclass(frozen=True)
class Experiment:
    """One experiment's command line: its help, options, and the call they make."""

    help: str
    add_options: Callable[[argparse.ArgumentParser], None]
    kwargs: Callable[[argparse.Namespace], dict[str, Any]]
    run: Callable[..., StudyResult]
    check: Callable[..., None] | None = None


EXPERIMENTS: dict[str, Experiment] = {
    "friction": Experiment(friction.HELP, _friction_options, _friction_kwargs, friction.run,
                           friction.check),
    "viscoelastic": Experiment(viscoelastic.HELP, _viscoelastic_options, _viscoelastic_kwargs,
                               viscoelastic.run, viscoelastic.check),
    "fetch-rate": Experiment(fetch_rate.HELP, _fetch_rate_options, _fetch_rate_kwargs,
                             fetch_rate.run),
}


def make_out_dir(path: Path) -> Path | None:
    """Create ``path`` (parents too); the topmost directory this created, None if it existed."""
    top = None
    for q in (path.absolute(), *path.absolute().parents):
        if q.exists():
            break
        top = q
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise UsageError(f"{PREFIX}: --out: cannot create {str(path)!r}: "
                         f"{exc.strerror}") from None
    return top


def save_figure(fig: Any, path: Path) -> None:
    """Save a matplotlib figure as PNG atomically and close it."""
    import matplotlib.pyplot as plt

    tmp = path.with_name(path.stem + ".part.png")
    try:
        fig.savefig(tmp, dpi=110, bbox_inches="tight")
        os.replace(tmp, path)
    except OSError as exc:
        tmp.unlink(missing_ok=True)
        raise UsageError(f"cannot write {str(path)!r}: {exc.strerror}") from None
    finally:
        plt.close(fig)


def write_result(result: StudyResult, out: Path) -> list[Path]:
    """Write every table (markdown and CSV), text and figure of ``result`` under ``out``."""
    written: list[Path] = []
    for table in result.tables:
        for ext, text in ((".md", table.markdown()), (".csv", table.csv())):
            written.append(out / f"{table.stem}{ext}")
            write_text(written[-1], text)
    for rel, text in result.texts.items():
        written.append(out / rel)
        written[-1].parent.mkdir(parents=True, exist_ok=True)
        write_text(written[-1], text)
    for rel, fig in result.figures.items():
        written.append(out / rel)
        written[-1].parent.mkdir(parents=True, exist_ok=True)
        save_figure(fig, written[-1])
    return written


def _kwargs_checked(exp: Experiment, args: argparse.Namespace) -> dict[str, Any]:
    """The experiment's keyword arguments, every one checked; a bad one is one usage line."""
    kwargs = exp.kwargs(args)
    if exp.check is not None:
        try:
            exp.check(**{k: v for k, v in kwargs.items() if k != "seed"})
        except StudyOptionError as exc:
            raise UsageError(f"{PREFIX}: --{exc.name.replace('_', '-')} {exc.detail}") from None
    return kwargs


def cmd_reproduce(args: argparse.Namespace) -> int:
    require_extra("reproduce", "figures")
    exp = EXPERIMENTS[args.experiment]
    kwargs = _kwargs_checked(exp, args)  # before --out is created or any run starts
    created = make_out_dir(args.out)
    try:
        result = exp.run(**kwargs, show_progress=True)
        written = write_result(result, args.out)
    except BaseException:
        # A failed run (diverged, interrupted) must not leave behind a directory it made and
        # never wrote a file into.
        if created is not None and not any(q.is_file() for q in created.rglob("*")):
            shutil.rmtree(created, ignore_errors=True)
        raise
    for line in result.summary:
        print(line)
    print(f"wrote {', '.join(str(p) for p in written)}")
    return 0


def add_options(p: argparse.ArgumentParser) -> None:
    """The options of ``food-fetch reproduce``."""
    exp = p.add_subparsers(dest="experiment", required=True, metavar="EXPERIMENT",
                           parser_class=type(p))
    for name, spec in EXPERIMENTS.items():
        ep = exp.add_parser(name, help=spec.help, description=spec.help)
        ep.add_argument("--out", type=out_dir, required=True, metavar="DIR",
                        help="folder for the tables and figures (created if missing, once the "
                        "other options are checked)")
        ep.add_argument("--seed", type=seed, default=0, metavar="N",
                        help="seed for every random choice (default: 0)")
        spec.add_options(ep)
        ep.set_defaults(func=cmd_reproduce)
