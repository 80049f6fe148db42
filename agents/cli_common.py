"""Pieces every ``food-fetch`` subcommand shares: the one-line usage error, typed number
parsers, writable-path checks, the food and clamp options and atomic JSON writes."""

from __future__ import annotations

import argparse
import json
import math
import os
from pathlib import Path
from typing import Any

EXIT_USAGE = 2


class UsageError(Exception):
    """A mistake in the command line or its input, reported as one line with exit code 2."""


class Parser(argparse.ArgumentParser):
    def error(self, message: str) -> None:  # argparse would print usage + message
        raise UsageError(f"{self.prog}: {message}")


def finite(kind: type = float):
    def parse(text: str) -> float:
        try:
            value = kind(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
        if not math.isfinite(value):
            raise argparse.ArgumentTypeError(f"not a finite number: {text!r}")
        return value

    parse.__name__ = kind.__name__
    return parse


def writable(path: str) -> Path:
    p = Path(path)
    parent = p.parent if str(p.parent) else Path(".")
    if not parent.is_dir():
        raise argparse.ArgumentTypeError(f"directory does not exist: {str(parent)!r}")
    if not os.access(parent, os.W_OK) or (p.exists() and not os.access(p, os.W_OK)):
        raise argparse.ArgumentTypeError(f"cannot write to {path!r}")
    return p


def add_food_options(p: argparse.ArgumentParser) -> None:
    """The food, clamp and seed options shared by simulate and estimate."""
    from fetch_env.controller import FetchAction
    from fetch_env.materials import Material

    m, a = Material(), FetchAction()
    g = p.add_argument_group("food")
    g.add_argument(
        "--shape",
        choices=("cube", "ellipsoid", "sphere"),
        default="cube",
        help="piece shape (default: cube)",
    )
    g.add_argument(
        "--size",
        type=finite(),
        default=0.015,
        metavar="M",
        help="piece size [m], 0.006 to 0.025 (default: 0.015)",
    )
    g.add_argument(
        "--young",
        type=finite(),
        default=m.young,
        metavar="PA",
        help=f"instantaneous Young's modulus E_0 [Pa] (default: {m.young:g})",
    )
    g.add_argument(
        "--poisson",
        type=finite(),
        default=m.poisson,
        metavar="NU",
        help=f"Poisson's ratio in [0, 0.5) (default: {m.poisson})",
    )
    g.add_argument(
        "--density",
        type=finite(),
        default=m.density,
        metavar="KG_M3",
        help=f"density [kg/m^3] (default: {m.density:g})",
    )
    g.add_argument(
        "--g1",
        type=finite(),
        default=m.g1,
        metavar="G",
        help=f"Prony g_1 in [0, 1) (default: {m.g1})",
    )
    g.add_argument(
        "--tau1",
        type=finite(),
        default=m.tau1,
        metavar="S",
        help=f"Prony tau_1 [s] (default: {m.tau1})",
    )
    g.add_argument(
        "--mu",
        type=finite(),
        default=m.mu,
        metavar="MU",
        help=f"half-spoon/food friction coefficient (default: {m.mu})",
    )
    g.add_argument(
        "--plate-mu",
        type=finite(),
        default=m.plate_mu,
        metavar="MU",
        help=f"plate/food friction coefficient (default: {m.plate_mu})",
    )
    g.add_argument(
        "--yield-strain",
        type=finite(),
        default=0.0,
        metavar="EPS",
        help="plastic yield strain; 0 = no plasticity (default: 0)",
    )
    c = p.add_argument_group("clamp")
    c.add_argument(
        "--theta-d",
        type=finite(),
        default=None,
        metavar="RAD",
        help="preset angular displacement from the open pose [rad] (default: 0.045; "
        "0.0244 for the relaxation probe)",
    )
    c.add_argument(
        "--omega",
        type=finite(),
        default=None,
        metavar="RAD_S",
        help="clamping angular velocity [rad/s] (default: 0.1; 0.02 for the relaxation probe)",
    )
    c.add_argument(
        "--lift-speed",
        type=finite(),
        default=a.lift_speed,
        metavar="M_S",
        help=f"lifting speed [m/s] (default: {a.lift_speed})",
    )
    c.add_argument(
        "--hold",
        type=finite(),
        default=None,
        metavar="S",
        help="hold at theta_d [s] (default: 1 for fetch, 15 for relaxation, 0.5 for slip)",
    )
    p.add_argument(
        "--seed",
        type=finite(int),
        default=0,
        metavar="N",
        help="seed for every random choice (default: 0)",
    )


def write_json(path: Path, payload: dict[str, Any]) -> None:
    tmp = path.with_name(path.name + ".part")
    try:
        with open(tmp, "w") as fh:
            json.dump(payload, fh)
        os.replace(tmp, path)
    except OSError as exc:
        tmp.unlink(missing_ok=True)
        raise UsageError(f"cannot write {str(path)!r}: {exc.strerror}") from None
