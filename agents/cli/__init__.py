"""The ``food-fetch`` command line: a dispatcher over one module per subcommand.

Each ``agents/cli/<name>.py`` has ``HELP`` and ``DESCRIPTION`` (for ``--help``),
``add_options(parser)`` and ``cmd_<name>(args) -> int`` (the exit code);
:mod:`agents.cli.common` holds the options, parsers and error handling they share.  A user's
mistake (a bad number, an unknown choice, an unwritable path) prints one line on stderr and
exits with code 2, never a traceback.
"""

from __future__ import annotations

import argparse
import importlib
import sys
from collections.abc import Sequence

from agents.cli.common import EXIT_USAGE, Parser, UsageError

__all__ = ["SUBCOMMANDS", "build_parser", "main", "version"]

# One module per subcommand, in the order ``--help`` lists them.
SUBCOMMANDS: tuple[str, ...] = ("simulate", "estimate", "reproduce", "train", "evaluate")


def version() -> str:
    """The installed package's version (its metadata, as ``pip show food-fetch`` gives it);
    "unknown" when the source tree is run without being installed."""
    from importlib.metadata import PackageNotFoundError
    from importlib.metadata import version as metadata_version

    try:
        return metadata_version("food-fetch")
    except PackageNotFoundError:
        return "unknown (not installed: pip install -e .)"


def build_parser() -> argparse.ArgumentParser:
    parser = Parser(
        prog="food-fetch",
        description=(
            "Simulate a two-half-spoon meal-assisting robot fetching soft viscoelastic food, "
            "estimate the food's viscoelasticity and friction, and train and evaluate agents."
        ),
    )
    parser.add_argument("--version", action="version", version=f"food-fetch {version()}",
                        help="print the installed version of food-fetch and exit")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=Parser)
    for name in SUBCOMMANDS:
        module = importlib.import_module(f"agents.cli.{name}")
        p = sub.add_parser(name, help=module.HELP, description=module.DESCRIPTION)
        module.add_options(p)
        p.set_defaults(func=getattr(module, f"cmd_{name}"))
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    from fetch_env.errors import InvalidParameterError, SimulationDivergedError
    from fetch_env.parallel import WorkerLostError, stop_exit_code

    try:
        args = build_parser().parse_args(argv)
        return int(args.func(args))
    except UsageError as exc:
        print(str(exc), file=sys.stderr)
    except InvalidParameterError as exc:
        print(f"food-fetch: error: {exc}", file=sys.stderr)
    except SimulationDivergedError as exc:
        print(f"food-fetch: error: {exc.one_line()}", file=sys.stderr)
    except WorkerLostError as exc:  # not the user's mistake: the machine's
        print(f"food-fetch: error: {exc}", file=sys.stderr)
        return 1
    except KeyboardInterrupt as exc:  # Ctrl-C, or SIGTERM / SIGHUP raised as one (its name)
        name = exc.args[0] if exc.args and isinstance(exc.args[0], str) else ""
        print(f"food-fetch: interrupted{f' ({name})' if name else ''}", file=sys.stderr)
        return stop_exit_code(exc)
    return EXIT_USAGE

