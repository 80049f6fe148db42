"""The ``food-fetch`` command line.

A user's mistake (a bad number, an unknown choice, an unwritable path) prints one line on
stderr and exits with code 2, never a traceback.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

EXIT_USAGE = 2


class UsageError(Exception):
    """A mistake in the command line or its input, reported as one line with exit code 2."""


class _Parser(argparse.ArgumentParser):
    def error(self, message: str) -> None:  # argparse would print usage + message
        raise UsageError(f"{self.prog}: {message}")


def _finite(kind: type = float):
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


def _writable(path: str) -> Path:
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
    g.add_argument("--shape", choices=("cube", "ellipsoid", "sphere"), default="cube",
                   help="piece shape (default: cube)")
    g.add_argument("--size", type=_finite(), default=0.015, metavar="M",
                   help="piece size [m], 0.006 to 0.025 (default: 0.015)")
    g.add_argument("--young", type=_finite(), default=m.young, metavar="PA",
                   help=f"instantaneous Young's modulus E_0 [Pa] (default: {m.young:g})")
    g.add_argument("--poisson", type=_finite(), default=m.poisson, metavar="NU",
                   help=f"Poisson's ratio in [0, 0.5) (default: {m.poisson})")
    g.add_argument("--density", type=_finite(), default=m.density, metavar="KG_M3",
                   help=f"density [kg/m^3] (default: {m.density:g})")
    g.add_argument("--g1", type=_finite(), default=m.g1, metavar="G",
                   help=f"Prony g_1 in [0, 1) (default: {m.g1})")
    g.add_argument("--tau1", type=_finite(), default=m.tau1, metavar="S",
                   help=f"Prony tau_1 [s] (default: {m.tau1})")
    g.add_argument("--mu", type=_finite(), default=m.mu, metavar="MU",
                   help=f"half-spoon/food friction coefficient (default: {m.mu})")
    g.add_argument("--plate-mu", type=_finite(), default=m.plate_mu, metavar="MU",
                   help=f"plate/food friction coefficient (default: {m.plate_mu})")
    g.add_argument("--yield-strain", type=_finite(), default=0.0, metavar="EPS",
                   help="plastic yield strain; 0 = no plasticity (default: 0)")
    c = p.add_argument_group("clamp")
    c.add_argument("--theta-d", type=_finite(), default=None, metavar="RAD",
                   help="preset angular displacement from the open pose [rad] (default: 0.045; "
                        "0.0244 for the relaxation probe)")
    c.add_argument("--omega", type=_finite(), default=None, metavar="RAD_S",
                   help="clamping angular velocity [rad/s] (default: 0.1; 0.02 for the "
                        "relaxation probe)")
    c.add_argument("--lift-speed", type=_finite(), default=a.lift_speed, metavar="M_S",
                   help=f"lifting speed [m/s] (default: {a.lift_speed})")
    c.add_argument("--hold", type=_finite(), default=None, metavar="S",
                   help="hold at theta_d [s] (default: 1 for fetch, 15 for relaxation, 0.5 "
                        "for slip)")
    p.add_argument("--seed", type=_finite(int), default=0, metavar="N",
                   help="seed for every random choice (default: 0)")


EXPERIMENT_DEFAULTS = {"fetch": (0.045, 0.1, 1.0), "relaxation": (0.0244, 0.02, 15.0),
                       "slip": (0.045, 0.1, 0.5)}


def _build(args: argparse.Namespace) -> tuple[Any, Any]:
    """Validated pieces and action from the options (raises before any simulation)."""
    from fetch_env.controller import FetchAction
    from fetch_env.layouts import Piece
    from fetch_env.materials import Material

    theta_d, omega, hold = EXPERIMENT_DEFAULTS[args.experiment]
    material = Material(young=args.young, poisson=args.poisson, density=args.density,
                        g1=args.g1, tau1=args.tau1, mu=args.mu, plate_mu=args.plate_mu,
                        yield_strain=args.yield_strain)
    pieces = (Piece(args.shape, args.size, material),)
    action = FetchAction(theta_d=args.theta_d if args.theta_d is not None else theta_d,
                         omega=args.omega if args.omega is not None else omega,
                         lift_speed=args.lift_speed,
                         hold=args.hold if args.hold is not None else hold)
    return pieces, action


def cmd_simulate(args: argparse.Namespace) -> int:
    from fetch_env.controller import FetchSimulator

    pieces, action = _build(args)
    result = FetchSimulator(pieces).run(args.experiment, action)
    out = result.to_dict(traces=True)
    out["seed"] = args.seed
    if args.json is not None:
        _write_json(args.json, out)
    tr = result.traces
    ml, mr = tr["moment_left"], tr["moment_right"]
    print(f"experiment        {result.experiment}  ({len(tr['t'])} samples at "
          f"{1 / (tr['t'][1] - tr['t'][0]):.0f} Hz, {result.n_steps} steps)")
    print(f"food              {pieces[0].shape} {pieces[0].size * 1000:g} mm, "
          f"E_0 {args.young:g} Pa, g1 {args.g1:g}, tau1 {args.tau1:g} s, mu {args.mu:g}")
    print(f"geometry          L {result.geometry['L'] * 1000:.2f} mm, theta_0 "
          f"{result.geometry['theta_0']:.4f} rad")
    print(f"action            theta_d {action.theta_d:g} rad, omega {action.omega:g} rad/s, "
          f"lift {action.lift_speed * 1000:g} mm/s, hold {action.hold:g} s")
    print(f"peak moment       {ml.max():.4f} / {mr.max():.4f} N m (left / right)")
    print(f"final moment      {ml[-1]:.4f} / {mr[-1]:.4f} N m")
    for k, p in enumerate(result.pieces):
        print(f"piece {k}           fetched {p['fetched']}, max LE clamp "
              f"{p['max_log_strain_clamp']:.3f}, lift {p['max_log_strain_lift']:.3f}")
    print(f"fetch rate        {result.fetch_rate:.2f} (by mass {result.fetch_rate_mass:.2f})")
    print(f"speed             {tr['t'][-1] / result.wall_time:.1f}x real time "
          f"({result.wall_time:.2f} s wall)")
    if args.json is not None:
        print(f"wrote             {args.json}")
    return 0


def _write_json(path: Path, payload: dict[str, Any]) -> None:
    tmp = path.with_name(path.name + ".part")
    try:
        with open(tmp, "w") as fh:
            json.dump(payload, fh)
        os.replace(tmp, path)
    except OSError as exc:
        tmp.unlink(missing_ok=True)
        raise UsageError(f"cannot write {str(path)!r}: {exc.strerror}") from None


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="food-fetch", description=(
        "Simulate a two-half-spoon meal-assisting robot fetching soft viscoelastic food."))
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)
    sim = sub.add_parser("simulate", help="run one fetch or probe experiment on one piece",
                         description="Run the fetch (clamp, hold, lift, air hold), the "
                                     "moment-relaxation probe or the induced-slip probe on one "
                                     "food piece and print or save the result.")
    sim.add_argument("--experiment", choices=("fetch", "relaxation", "slip"), default="fetch",
                     help="which experiment (default: fetch)")
    add_food_options(sim)
    sim.add_argument("--json", type=_writable, default=None, metavar="FILE",
                     help="write the full result, traces included, as JSON")
    sim.set_defaults(func=cmd_simulate)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    from fetch_env.errors import InvalidParameterError, SimulationDivergedError

    try:
        args = build_parser().parse_args(argv)
        return int(args.func(args))
    except UsageError as exc:
        print(str(exc), file=sys.stderr)
    except InvalidParameterError as exc:
        print(f"food-fetch: error: {exc}", file=sys.stderr)
    except SimulationDivergedError as exc:
        print(f"food-fetch: error: {exc.one_line()}", file=sys.stderr)
    except KeyboardInterrupt:
        print("food-fetch: interrupted", file=sys.stderr)
        return 130
    return EXIT_USAGE


if __name__ == "__main__":
    sys.exit(main())
