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


def clip_records(pieces: tuple[Any, ...], result: Any) -> list[dict[str, Any]]:
    """What the run changed of the given values (``fetch_env.clipping``): moduli above the
    conditioning limit simulated at it, and theta_d stopped at the controller's end stop."""
    from fetch_env.scene import young_caps
    from fetch_env.spaces import end_stop_records

    return [*young_caps(pieces, result.timestep),
            *end_stop_records(result.action.theta_d, result.extra,
                              result.geometry["theta_closed"])]


def cmd_simulate(args: argparse.Namespace) -> int:
    from fetch_env.clipping import reported_elsewhere
    from fetch_env.controller import FetchSimulator

    pieces, action = _build(args)
    with reported_elsewhere():  # below, in the text and the JSON's "clipped"
        result = FetchSimulator(pieces).run(args.experiment, action)
    clipped = clip_records(pieces, result)
    out = result.to_dict(traces=True)
    out["seed"] = args.seed
    out["clipped"] = clipped
    if args.json is not None:
        write_json(args.json, out)
    _print_result(args, pieces, action, result, clipped)
    return 0


def _print_result(args: argparse.Namespace, pieces: tuple[Any, ...], action: Any,
                  result: Any, clipped: list[dict[str, Any]]) -> None:
    """The text report: experiment, food (and the modulus simulated where it was capped),
    geometry, action (and where the clamp stopped short), per-piece outcomes, speed."""
    from fetch_env.controller import CLOSED_MARGIN
    from fetch_env.scene import BLADE_HALF_THICKNESS

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
    for rec in clipped:
        if rec["rule"] == "young":
            print(f"                  E_0 capped: {rec['applied']:.3g} Pa simulated, not "
                  f"{rec['given']:g} Pa ({rec['reason']})")
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


def add_options(p: argparse.ArgumentParser) -> None:
    """The options of ``food-fetch simulate``."""
    p.add_argument(
        "--experiment",
        choices=("fetch", "relaxation", "slip"),
        default="fetch",
        help="which experiment (default: fetch)",
    )
    add_food_options(p)
    help_caps(p)
    p.add_argument(
        "--json",
        type=writable,
        default=None,
        metavar="FILE",
        help="write the full result, traces included, as JSON",
    )


def help_caps(p: argparse.ArgumentParser) -> None:
    """State in --help the values the simulator caps (``fetch_env.clipping``): the
    modulus and the clamp angle (simulate's and estimate's food and clamp options)."""
    from fetch_env.controller import CLOSED_MARGIN

    young = p._option_string_actions["--young"]
    young.help = (f"{young.help}; above MuJoCo's conditioning limit 1e4 rho s^2 / dt^2 "
                  "(9e7 Pa for a 15 mm, 1000 kg/m^3 cube at the 5 ms step) it is simulated at "
                  "the limit, said in the output and the JSON's \"clipped\"")
    theta = p._option_string_actions["--theta-d"]
    theta.help = (f"{theta.help}; the controller's end stop, {CLOSED_MARGIN:g} rad before the "
                  "half-spoons' tips meet, stops a larger one there (said in the output)")
