"""``food-fetch simulate``: one fetch or probe experiment on one piece."""

from __future__ import annotations

import argparse
from typing import Any

from agents.cli.common import add_food_options, make_material, writable, write_json

HELP = "run one fetch or probe experiment on one piece"
DESCRIPTION = ("Run the fetch (clamp, hold, lift, air hold), the "
               "moment-relaxation probe or the induced-slip probe on one "
               "food piece and print or save the result.")

EXPERIMENT_DEFAULTS = {
    "fetch": (0.045, 0.1, 1.0),
    "relaxation": (0.0244, 0.02, 15.0),
    "slip": (0.045, 0.1, 0.5),
}


def _build(args: argparse.Namespace) -> tuple[Any, Any]:
    """Validated pieces and action from the options (raises before any simulation)."""
    from fetch_env.controller import FetchAction
    from fetch_env.layouts import Piece

    theta_d, omega, hold = EXPERIMENT_DEFAULTS[args.experiment]
    material = make_material(args)
    pieces = (Piece(args.shape, args.size, material),)
    action = FetchAction(
        theta_d=args.theta_d if args.theta_d is not None else theta_d,
        omega=args.omega if args.omega is not None else omega,
        lift_speed=args.lift_speed,
        hold=args.hold if args.hold is not None else hold,
    )
    return pieces, action


def cmd_simulate(args: argparse.Namespace) -> int:
    from fetch_env.controller import CLOSED_MARGIN, FetchSimulator
    from fetch_env.scene import BLADE_HALF_THICKNESS

    pieces, action = _build(args)
    result = FetchSimulator(pieces).run(args.experiment, action)
    out = result.to_dict(traces=True)
    out["seed"] = args.seed
    if args.json is not None:
        write_json(args.json, out)
    tr = result.traces
    ml, mr = tr["moment_left"], tr["moment_right"]
    print(
        f"experiment        {result.experiment}  ({len(tr['t'])} samples at "
        f"{1 / (tr['t'][1] - tr['t'][0]):.0f} Hz, {result.n_steps} steps)"
    )
    print(
        f"food              {pieces[0].shape} {pieces[0].size * 1000:g} mm, "
        f"E_0 {args.young:g} Pa, g1 {args.g1:g}, tau1 {args.tau1:g} s, mu {args.mu:g}"
    )
    print(
        f"geometry          L {result.geometry['L'] * 1000:.2f} mm, theta_0 "
        f"{result.geometry['theta_0']:.4f} rad (faces vertical at the open pose), theta_closed "
        f"{result.geometry['theta_closed']:.4f} rad, gap {result.geometry['gap'] * 1000:g} mm"
    )
    print(
        f"action            theta_d {action.theta_d:g} rad, omega {action.omega:g} rad/s, "
        f"lift {action.lift_speed * 1000:g} mm/s, hold {action.hold:g} s"
    )
    extra = result.extra
    if extra["stalled_at"] is not None:
        print(f"                  the motor stalled at {extra['stalled_at']:.4f} rad "
              "(its 2 N m stall moment): theta_d was not reached")
    elif extra["theta_d_applied"] < action.theta_d:
        print(f"                  theta_d capped at {extra['theta_d_applied']:.4f} rad: the end "
              f"stop, {CLOSED_MARGIN:g} rad before the faces meet at "
              f"{result.geometry['theta_closed']:.4f}")
    print(f"peak moment       {ml.max():.4f} / {mr.max():.4f} N m (left / right)")
    print(f"final moment      {ml[-1]:.4f} / {mr[-1]:.4f} N m")
    for k, p in enumerate(result.pieces):
        print(
            f"piece {k}           fetched {p['fetched']}, max LE clamp "
            f"{p['max_log_strain_clamp']:.3f}, lift {p['max_log_strain_lift']:.3f}"
        )
        if p["passed_through"]:
            print(f"                  PASSED THROUGH a blade or the plate (deepest vertex "
                  f"{p['max_blade_overlap'] * 1000:.1f} mm into a blade, "
                  f"{2000 * BLADE_HALF_THICKNESS:g} mm thick; lowest "
                  f"{p['lowest_z_ever'] * 1000:.1f} mm): squeezed past what this simulator "
                  "models, so its LE is no measurement and it is not counted fetched")
    if extra["mujoco_warnings"]:
        print(f"MuJoCo warnings   {extra['mujoco_warnings']}")
    print(f"fetch rate        {result.fetch_rate:.2f} (by mass {result.fetch_rate_mass:.2f})")
    print(
        f"speed             {tr['t'][-1] / result.wall_time:.1f}x real time "
        f"({result.wall_time:.2f} s wall)"
    )
    if args.json is not None:
        print(f"wrote             {args.json}")
    return 0


def add_options(p: argparse.ArgumentParser) -> None:
    """The options of ``food-fetch simulate``."""
    p.add_argument(
        "--experiment",
        choices=("fetch", "relaxation", "slip"),
        default="fetch",
        help="which experiment (default: fetch)",
    )
    add_food_options(p)
    p.add_argument(
        "--json",
        type=writable,
        default=None,
        metavar="FILE",
        help="write the full result, traces included, as JSON",
    )
