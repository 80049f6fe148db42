"""Pieces every ``food-fetch`` subcommand shares: the one-line usage error, typed number
parsers, writable-path checks, the food and clamp options and atomic JSON writes."""

from __future__ import annotations

import argparse
import contextlib
import importlib.util
import json
import math
import os
from pathlib import Path
from typing import Any

EXIT_USAGE = 2
# The id evaluate and train run without --env: the benchmark id (a -v0 id would print
# gymnasium's out-of-date note on every default run).
DEFAULT_ENV = "FoodFetch-Block-v1"


class UsageError(Exception):
    """A mistake in the command line or its input, reported as one line with exit code 2."""


# The optional extras (pyproject.toml) and the modules each brings, by import name.
EXTRAS: dict[str, tuple[str, ...]] = {
    "figures": ("matplotlib", "tqdm"),
    "train": ("stable_baselines3", "torch", "yaml", "tqdm"),
    "zoo": ("rl_zoo3",),
    "datasets": ("minari", "h5py", "PIL"),
    "ray": ("ray",),
    "rllib": ("ray", "torch", "tree", "lz4"),  # dm_tree, lz4: RLlib's own dependencies
}


def require_extra(command: str, extra: str) -> None:
    """Stop with a one-line usage error, before any work starts, when ``command`` needs an
    extra that is not installed (the core installs only gymnasium, mujoco, numpy, scipy)."""
    missing = [m for m in EXTRAS[extra] if importlib.util.find_spec(m) is None]
    if missing:
        raise UsageError(f"food-fetch {command}: needs the {extra} extra (missing: "
                         f"{', '.join(missing)}): pip install -e '.[{extra}]'")


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


def integer(text: str) -> int:
    """An integer option (a finite number with no fractional part)."""
    return int(finite(int)(text))


def positive_int(text: str) -> int:
    """An integer option >= 1."""
    value = integer(text)
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be >= 1, got {text!r}")
    return value


def out_dir(path: str) -> Path:
    """``--out``: a directory that exists or can be created (its nearest existing ancestor is
    a writable directory).  Only checked here: the command creates it once every input is known
    good, so a rejected call leaves no empty directory behind."""
    if not path.strip():  # Path("") is the current directory: say so rather than write there
        raise argparse.ArgumentTypeError(f"not a directory name: {path!r}")
    p = Path(path)
    if p.exists() and not p.is_dir():
        raise argparse.ArgumentTypeError(f"not a directory: {path!r}")
    probe = p.absolute()
    while not probe.exists():
        probe = probe.parent
    if not probe.is_dir():
        raise argparse.ArgumentTypeError(f"cannot create {path!r}: {str(probe)!r} is not a "
                                         "directory")
    if not os.access(probe, os.W_OK | os.X_OK):
        raise argparse.ArgumentTypeError(f"cannot write to {path!r}")
    return p


MAX_SEED = 2**32 - 1  # numpy's and gymnasium's seeds are unsigned 32-bit


def seed(text: str) -> int:
    """A seed: an integer in [0, 2**32 - 1], as numpy and gymnasium accept it."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not an integer: {text!r}") from None
    if not 0 <= value <= MAX_SEED:
        raise argparse.ArgumentTypeError(f"{value} is not in [0, {MAX_SEED}]")
    return value


def writable(path: str) -> Path:
    """A file path that can be written: a file name (not a directory) in an existing,
    writable directory, checked when the command line is parsed, before any work."""
    p = Path(path)
    if not p.name or p.name in (".", "..") or p.is_dir():
        raise argparse.ArgumentTypeError(f"not a file name: {path!r}")
    from agents.atomic import written_as_is

    if p.exists() and written_as_is(p) and os.access(p, os.W_OK):
        return p  # /dev/stdout, a FIFO: written as they are (agents.atomic), not replaced
    parent = p.parent if str(p.parent) else Path(".")
    if not parent.is_dir():
        raise argparse.ArgumentTypeError(f"directory does not exist: {str(parent)!r}")
    if not os.access(parent, os.W_OK) or (p.exists() and not os.access(p, os.W_OK)):
        raise argparse.ArgumentTypeError(f"cannot write to {path!r}")
    # the atomic writer puts its temporary file beside what a symlink points to
    _try_a_file_in(Path(os.path.realpath(p)).parent if p.is_symlink() else parent, path)
    return p


def _try_a_file_in(directory: Path, path: str) -> None:
    """Create and remove a file in ``directory``, as the atomic writer will (a temporary file
    beside ``path``): a directory that permissions allow but that refuses files (/proc, a
    read-only mount) is refused now rather than after the run."""
    import tempfile

    try:
        fd, tmp = tempfile.mkstemp(dir=directory, prefix=".food-fetch-check-")
    except OSError as exc:
        raise argparse.ArgumentTypeError(f"cannot write to {path!r}: "
                                         f"{exc.strerror or exc}") from None
    with contextlib.suppress(OSError):  # a directory that takes files but keeps them
        os.close(fd)
        os.unlink(tmp)


def require_distinct(command: str, paths: dict[str, Path | str | None]) -> None:
    """Refuse two options that name one file (an output would overwrite an input, or another
    output): ``paths`` maps each option to its path or None.  Paths written as they are
    (/dev/stdout, a FIFO) may be shared."""
    from agents.atomic import written_as_is

    seen: dict[str, str] = {}
    for option, path in paths.items():
        if path is None or (Path(path).exists() and written_as_is(Path(path))):
            continue
        key = os.path.realpath(path)
        if key in seen:
            raise UsageError(f"{command}: {seen[key]} and {option} name the same file "
                             f"{str(path)!r}")
        seen[key] = option


def add_food_options(p: argparse.ArgumentParser) -> None:
    """The food, clamp and seed options shared by simulate and estimate."""
    from fetch_env.controller import FetchAction
    from fetch_env.materials import Material

    m, a = Material(), FetchAction()
    g = p.add_argument_group("food")
    g.add_argument("--shape", choices=("cube", "ellipsoid", "sphere"), default="cube",
                   help="piece shape (default: cube)")
    # (option, default, metavar, help): every number parsed by `finite`, defaults from the
    # Material and FetchAction dataclasses so the help can never disagree with the code.
    food: tuple[tuple[str, float, str, str], ...] = (
        ("--size", 0.015, "M", "piece size [m], 0.006 to 0.025"),
        ("--young", m.young, "PA", "instantaneous Young's modulus E_0 [Pa]"),
        ("--poisson", m.poisson, "NU", "Poisson's ratio in [0, 0.5)"),
        ("--density", m.density, "KG_M3", "density [kg/m^3]"),
        ("--g1", m.g1, "G", "Prony g_1 in [0, 1)"),
        ("--tau1", m.tau1, "S", "Prony tau_1 [s], up to 1e6"),
        ("--mu", m.mu, "MU", "half-spoon/food friction coefficient, 0 to 10"),
        ("--plate-mu", m.plate_mu, "MU", "plate/food friction coefficient, 0 to 10"),
        ("--yield-strain", 0.0, "EPS", "plastic yield strain; 0 = no plasticity"),
    )
    for option, default, metavar, text in food:
        g.add_argument(option, type=finite(), default=default, metavar=metavar,
                       help=f"{text} (default: {default:g})")
    c = p.add_argument_group("clamp")
    clamp: tuple[tuple[str, float | None, str, str], ...] = (
        ("--theta-d", None, "RAD", "preset angular displacement from the open pose [rad] "
         "(default: 0.045; 0.0244 for the relaxation probe)"),
        ("--omega", None, "RAD_S", "clamping angular velocity [rad/s] (default: 0.1; 0.02 "
         "for the relaxation probe)"),
        ("--lift-speed", a.lift_speed, "M_S", f"lifting speed [m/s] (default: {a.lift_speed})"),
        ("--hold", None, "S", "hold at theta_d [s] (default: 1 for fetch, 15 for relaxation, "
         "0.5 for slip)"),
    )
    for option, default, metavar, text in clamp:
        c.add_argument(option, type=finite(), default=default, metavar=metavar, help=text)
    p.add_argument("--seed", type=seed, default=0, metavar="N",
                   help="seed for every random choice (default: 0)")


def add_ray_options(p: argparse.ArgumentParser, items: str, note: str = "",
                    batch_default: int | None = None) -> None:
    """``--ray [ADDRESS]`` and ``--ray-batch N``: ``items`` (e.g. "episodes") run as Ray
    tasks, with ``note`` said after the help's "Same numbers as --workers 1";
    ``batch_default``: the batch the caller takes when none is given (None:
    :func:`agents.ray_runner.batches`' default)."""
    p.add_argument("--ray", nargs="?", const="local", default=None, metavar="ADDRESS",
                   help=f"run the {items} as Ray tasks (the ray extra): alone, on a local Ray "
                   "instance of --workers CPUs; with ADDRESS ('auto', HOST:PORT of a head, "
                   "ray://HOST:PORT), on that cluster, every node having food-fetch "
                   f"installed. Same numbers as --workers 1{note}")
    default = (f"{batch_default}" if batch_default is not None else
               f"about four tasks per cluster CPU, at most 8 {items} each")
    p.add_argument("--ray-batch", type=positive_int, default=None, metavar="N",
                   help=f"with --ray, {items} per Ray task (default: {default})")


def check_ray_options(command: str, args: argparse.Namespace) -> None:
    """``--ray``: the extra installed, the address well formed and answering, checked before
    any work (:class:`UsageError`, one line naming ``command``); sets ``args.ray`` to the
    address as Ray takes it."""
    if args.ray is None:
        if args.ray_batch is not None:
            raise UsageError(f"{command}: --ray-batch needs --ray")
        return
    if importlib.util.find_spec("ray") is None:
        raise UsageError(f"{command}: --ray needs the ray extra: pip install -e '.[ray]'")
    from agents.ray_runner import RaySetupError, check_address, why_unreachable

    try:
        args.ray = check_address(args.ray)
    except RaySetupError as exc:
        raise UsageError(f"{command}: {exc}") from None
    why = why_unreachable(args.ray)
    if why is not None:
        raise UsageError(f"{command}: no Ray cluster answers at {args.ray!r} ({why})")


def make_material(args: argparse.Namespace) -> Any:
    """The :class:`fetch_env.materials.Material` of the food options (validated there)."""
    from fetch_env.materials import Material

    return Material(young=args.young, poisson=args.poisson, density=args.density, g1=args.g1,
                    tau1=args.tau1, mu=args.mu, plate_mu=args.plate_mu,
                    yield_strain=args.yield_strain)


def write_text(path: Path, text: str) -> None:
    """Write ``text`` to ``path`` atomically (:func:`agents.atomic.write_atomic`: a
    temporary file beside it, then ``os.replace``), so a reader never sees half a file."""
    from agents.atomic import write_atomic

    try:
        write_atomic(path, text)
    except OSError as exc:
        raise UsageError(f"cannot write {str(path)!r}: {exc.strerror or exc}") from None


def write_json(path: Path, payload: dict[str, Any]) -> None:
    """Write ``payload`` as JSON to ``path`` atomically."""
    write_text(path, json.dumps(payload))
