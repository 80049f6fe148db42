"""``food-fetch reproduce EXPERIMENT``: rerun one of the study's virtual experiments here and
write its tables (CSV and markdown) and figures (PNG) to a folder, the study's numbers beside
this project's.

Each experiment lives in its own module ``agents/reproduce_<name>.py`` (``-`` in the name
becomes ``_``) with this small interface:

* ``HELP: str`` -- one line for ``--help`` (optional);
* ``add_arguments(parser)`` -- adds the experiment's own options (optional); ``--out DIR`` and
  ``--seed N`` are added here for every experiment;
* ``check(args)`` -- validates the experiment's options, raising ``UsageError`` (optional;
  called before ``--out`` is created, so a rejected call leaves nothing behind);
* ``run(args) -> int`` -- does the work (required); ``args.out`` is an existing, writable
  :class:`pathlib.Path`.

Modules are imported lazily, when their experiment is chosen, so a missing or broken module
never stops the other experiments; choosing it prints one usage line and exits with 2.
"""

from __future__ import annotations

import argparse
import importlib
import os
import shutil
from pathlib import Path
from typing import Any

from agents.cli_common import UsageError, require_extra, seed

EXPERIMENTS: tuple[str, ...] = ("friction", "viscoelastic", "fetch-rate")
_HELP = {
    "friction": "Fig. 4: mu by induced slippage, cube/ellipsoid/sphere at mu 0.1/0.2/0.3/0.5",
    "viscoelastic": "Figs. 5-6: K1, K2, B, g1, tau1 from the moment at omega 0.01-0.04 rad/s",
    "fetch-rate": "the study's fetch-rate experiments (rows, two rows, diced mixes, speed)",
}


def module_name(experiment: str) -> str:
    return f"agents.reproduce_{experiment.replace('-', '_')}"


def load(experiment: str) -> Any | None:
    """The experiment's module, or None if it does not exist (yet)."""
    name = module_name(experiment)
    try:
        return importlib.import_module(name)
    except ModuleNotFoundError as exc:
        if exc.name == name:
            return None
        raise


def out_dir(path: str) -> Path:
    """``--out``: a directory that exists or can be created (its nearest existing ancestor is
    a writable directory).  Only checked here: :func:`cmd_reproduce` creates it once every
    input is known good, so a rejected call leaves no empty directory behind."""
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
        raise UsageError(f"food-fetch reproduce: --out: cannot create {str(path)!r}: "
                         f"{exc.strerror}") from None
    return top


# --------------------------------------------------------------------------------------------
# helpers the experiment modules share: atomic writes of tables and figures


def write_text(path: Path, text: str) -> None:
    """Write ``text`` to ``path`` atomically (a temporary file, then ``os.replace``)."""
    tmp = path.with_name(path.name + ".part")
    try:
        tmp.write_text(text)
        os.replace(tmp, path)
    except OSError as exc:
        tmp.unlink(missing_ok=True)
        raise UsageError(f"cannot write {str(path)!r}: {exc.strerror}") from None


def write_table(
    out: Path, stem: str, header: list[str], rows: list[list[Any]], title: str = ""
) -> tuple[Path, Path]:
    """Write ``rows`` as ``stem.csv`` and ``stem.md`` (a markdown table under ``title``)."""
    import csv
    import io

    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(header)
    w.writerows(rows)
    md = [f"### {title}", ""] if title else []
    md.append("| " + " | ".join(header) + " |")
    md.append("|" + "---|" * len(header))
    md += ["| " + " | ".join(str(c) for c in r) + " |" for r in rows]
    csv_path, md_path = out / f"{stem}.csv", out / f"{stem}.md"
    write_text(csv_path, buf.getvalue())
    write_text(md_path, "\n".join(md) + "\n")
    return csv_path, md_path


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


def pyplot() -> Any:
    """``matplotlib.pyplot`` on the non-interactive Agg backend."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def cmd_reproduce(args: argparse.Namespace) -> int:
    require_extra("reproduce", "figures")
    module = load(args.experiment)
    if module is None or not hasattr(module, "run"):
        raise UsageError(
            f"food-fetch reproduce: {args.experiment!r} is not available in this checkout "
            f"({module_name(args.experiment)} with run(args) is missing)"
        )
    if hasattr(module, "check"):
        module.check(args)  # every option, before --out is created or any run starts
    created = make_out_dir(args.out)
    try:
        return int(module.run(args))
    except BaseException:
        # A failed run (diverged, interrupted) must not leave behind a directory it made and
        # never wrote a file into.
        if created is not None and not any(q.is_file() for q in created.rglob("*")):
            shutil.rmtree(created, ignore_errors=True)
        raise


def register(sub: Any) -> None:
    p = sub.add_parser(
        "reproduce",
        help="rerun one of the study's virtual experiments, writing tables and figures",
        description="Rerun one of the study's virtual experiments in the simulator and write "
        "its tables (CSV, markdown) and figures (PNG) to --out, with the study's reported "
        "numbers (PAPER.md) beside this project's.",
    )
    exp = p.add_subparsers(
        dest="experiment", required=True, metavar="EXPERIMENT", parser_class=type(p)
    )
    for name in EXPERIMENTS:
        module = None
        try:
            module = load(name)
        except Exception:  # a broken module must not break the other experiments' CLI
            module = None
        help_text = getattr(module, "HELP", None) or _HELP[name]
        ep = exp.add_parser(name, help=help_text, description=help_text)
        ep.add_argument(
            "--out",
            type=out_dir,
            required=True,
            metavar="DIR",
            help="folder for the tables and figures (created if missing, once the "
            "other options are checked)",
        )
        ep.add_argument(
            "--seed",
            type=seed,
            default=0,
            metavar="N",
            help="seed for every random choice (default: 0)",
        )
        if module is not None and hasattr(module, "add_arguments"):
            module.add_arguments(ep)
        ep.set_defaults(func=cmd_reproduce)
