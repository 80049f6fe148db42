"""What a reproduction returns: its tables, texts and figures, in memory.

A reproduction (:mod:`agents.study.friction`, :mod:`agents.study.viscoelastic`,
:mod:`agents.study.fetch_rate`) computes; it never writes.  ``food-fetch reproduce`` writes what
it returns (each file through a temporary file and a rename), and a notebook can show the same
tables and figures without touching the disk.
"""

from __future__ import annotations

import csv
import io
from dataclasses import dataclass, field
from typing import Any


class StudyOptionError(ValueError):
    """A reproduction's option out of its range, raised before any simulation runs.

    ``name`` is the option's keyword (``slide_time``); ``detail`` says what was wrong
    (``must be in (0, 120] s, got 0``).
    """

    def __init__(self, name: str, detail: str) -> None:
        super().__init__(f"{name} {detail}")
        self.name = name
        self.detail = detail


def check_range(name: str, value: float, lo: float, hi: float, unit: str = "",
                lo_open: bool = False) -> None:
    """Raise :class:`StudyOptionError` unless ``lo <= value <= hi`` (``lo < value`` when
    ``lo_open``)."""
    ok = (lo < value if lo_open else lo <= value) and value <= hi
    if not ok:
        bracket = "(" if lo_open else "["
        suffix = f" {unit}" if unit else ""
        raise StudyOptionError(name, f"must be in {bracket}{_num(lo)}, {_num(hi)}]{suffix}, "
                                     f"got {value:g}")


def _num(x: float) -> str:
    """``x`` short: 0.001, 2, 1e6 (not 1e+06)."""
    return f"{x:g}".replace("e+0", "e").replace("e+", "e")


@dataclass
class Table:
    """One result table: written as ``<stem>.csv`` and ``<stem>.md`` (under ``title``)."""

    stem: str
    header: list[str]
    rows: list[list[Any]]
    title: str = ""

    def csv(self) -> str:
        """The table as CSV text (a header row, then one row per line)."""
        buf = io.StringIO()
        w = csv.writer(buf, lineterminator="\n")
        w.writerow(self.header)
        w.writerows(self.rows)
        return buf.getvalue()

    def markdown(self) -> str:
        """The table as a markdown table, under a ``###`` heading when it has a title."""
        md = [f"### {self.title}", ""] if self.title else []
        md.append("| " + " | ".join(self.header) + " |")
        md.append("|" + "---|" * len(self.header))
        md += ["| " + " | ".join(str(c) for c in r) + " |" for r in self.rows]
        return "\n".join(md) + "\n"


@dataclass
class StudyResult:
    """Everything one reproduction produced.

    Attributes:
        tables: result tables, each written as CSV and markdown.
        texts: other files by relative path (e.g. ``fetch_rate.json``), as text.
        figures: matplotlib figures by relative path (e.g. ``fig4_friction.png``).
        summary: lines for the user (the verdict in a sentence or a table).
    """

    tables: list[Table] = field(default_factory=list)
    texts: dict[str, str] = field(default_factory=dict)
    figures: dict[str, Any] = field(default_factory=dict)
    summary: list[str] = field(default_factory=list)

    def files(self) -> list[str]:
        """The relative paths a writer creates for this result, in order."""
        out = [f"{t.stem}{ext}" for t in self.tables for ext in (".md", ".csv")]
        return out + list(self.texts) + list(self.figures)


def pyplot() -> Any:
    """``matplotlib.pyplot`` on the non-interactive Agg backend (the ``figures`` extra)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def progress(items: list[Any], show: bool, desc: str, unit: str) -> Any:
    """``items`` wrapped in a tqdm bar when ``show`` (the ``figures`` extra brings tqdm)."""
    if not show:
        return items
    from tqdm import tqdm

    return tqdm(items, desc=desc, unit=unit)
