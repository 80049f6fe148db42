"""Recorded sensor traces read from a file, so the estimators can run on a real robot's logs.

Two formats (the full schema, with an example, is ``docs/traces_format.md``):

* **CSV**: optional leading comment lines ``# key: value`` (metadata: ``L``, ``theta_0``,
  ``clamp_start``, ``slide_start``, in SI units), then a header row of column names, then one
  row of numbers per sample.  Columns: ``t`` (s), ``theta`` (rad), ``moment_left`` and
  ``moment_right`` (N m), ``normal_left``, ``normal_right``, ``tangential_left``,
  ``tangential_right`` (N) and ``phase`` (the simulator's phase codes); other columns are
  ignored, so a log may carry more.
* **JSON**: what ``food-fetch simulate --json FILE`` writes (``traces``, ``geometry``,
  ``extra.t_clamp_start``, ``phases``, ``experiment``).  Only the columns of the file's
  experiment are read: a relaxation run's hinge angle and moments, a slip run's contact forces
  (a relaxation hold has contact forces too, but no slide to measure friction on).

Sign conventions are the estimators' (:mod:`estimators.sls`): ``theta`` is 0 at the open pose
and grows while the half-spoons close; a moment is positive when the food pushes the half-spoon
open and tared to 0 before contact; a normal force is positive pressing, a tangential force lies
along the slide (the friction estimator uses magnitudes).

Pure stdlib (``csv``, ``json``) and numpy: nothing is unpickled, nothing imports MuJoCo.  Every
problem with a file raises one :class:`TraceFileError` naming the file and what is wrong.
"""

from __future__ import annotations

import csv
import json
import math
import os
from collections import Counter
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from estimators.errors import MAX_SAMPLE, MIN_SAMPLE_INTERVAL, EstimationError, optional_real
from estimators.sls import ClampGeometry

__all__ = [
    "COLUMNS",
    "MIN_SAMPLES",
    "PHASES",
    "RELAXATION_COLUMNS",
    "SLIP_COLUMNS",
    "RecordedTraces",
    "TraceFileError",
    "load_traces",
]

# The estimators refuse fewer samples than this (relaxation and friction alike).
MIN_SAMPLES = 20
# Phase codes of the ``phase`` column: the index in this tuple (the simulator's order).
PHASES = ("settle", "clamp", "hold", "lift", "air", "slide")
RELAXATION_COLUMNS = ("theta", "moment_left", "moment_right")
SLIP_COLUMNS = ("normal_left", "normal_right", "tangential_left", "tangential_right")
COLUMNS = ("t", *RELAXATION_COLUMNS, *SLIP_COLUMNS, "phase")
METADATA_KEYS = ("L", "theta_0", "clamp_start", "slide_start")
# simulate's experiments and the columns each is read for; "fetch" lifts, so it has no probe.
EXPERIMENT_COLUMNS = {
    "relaxation": ("t", *RELAXATION_COLUMNS, "phase"),
    "slip": ("t", *SLIP_COLUMNS, "phase"),
}

Array = NDArray[np.float64]


class TraceFileError(EstimationError):
    """A traces file that cannot be used: its message names the file and the one problem."""

    def __init__(self, path: str | os.PathLike[str], problem: str) -> None:
        super().__init__(f"{os.fspath(path)}: {problem}")
        self.path = os.fspath(path)
        self.problem = problem


@dataclass(frozen=True, eq=False)
class RecordedTraces:
    """Validated traces from one file (SI units, read-only arrays of one length).

    Attributes:
        path: the file read.
        t: sample times, s, strictly increasing.
        theta: hinge angle, rad (None without relaxation data).
        moment_left, moment_right: each half-spoon's moment, N m (None likewise).
        normal_left, normal_right, tangential_left, tangential_right: contact forces, N
            (None without slip data).
        phase: phase codes (index in ``phases``), or None.
        geometry: the clamp geometry, None only when there is no relaxation data.
        clamp_start: time the clamp starts, s; earlier samples are left out of the relaxation
            fit and its time is counted from here (None: every sample, time as recorded).
        slide_start: time the slide starts, s (None: the friction estimator finds it).
        source: where each value came from, e.g. ``{"L": "geometry.L in the file"}``.
        phases: the names of ``phase``'s codes, in order (a JSON file's own ``phases``, else
            :data:`PHASES`).
    """

    path: str
    t: Array
    theta: Array | None
    moment_left: Array | None
    moment_right: Array | None
    normal_left: Array | None
    normal_right: Array | None
    tangential_left: Array | None
    tangential_right: Array | None
    phase: Array | None
    geometry: ClampGeometry | None
    clamp_start: float | None
    slide_start: float | None
    source: Mapping[str, str]
    phases: tuple[str, ...] = PHASES

    @property
    def probes(self) -> tuple[str, ...]:
        """The probes this file has data for: ``"relaxation"`` and/or ``"slip"``."""
        return tuple(
            name
            for name, cols in (("relaxation", RELAXATION_COLUMNS), ("slip", SLIP_COLUMNS))
            if all(getattr(self, c) is not None for c in cols)
        )

    def in_phase(self, name: str) -> Array | None:
        """Which samples the ``phase`` column marks as phase ``name`` (a boolean array), or
        None where the file has no phase column, no such phase or no sample in it."""
        if self.phase is None or name not in self.phases:
            return None
        marked = self.phase == self.phases.index(name)
        return marked if marked.any() else None

    def relaxation_inputs(self) -> tuple[Array, Array, Array, ClampGeometry]:
        """``(t, theta, M, geometry)`` for the viscoelastic estimators: from ``clamp_start`` on,
        time counted from it, ``M`` the mean of both half-spoons' moments (as the simulated
        relaxation probe feeds them)."""
        if (self.theta is None or self.moment_left is None or self.moment_right is None
                or self.geometry is None):
            raise TraceFileError(self.path, "no relaxation data (theta, moment_left, "
                                 "moment_right and the clamp geometry)")
        m = 0.5 * (self.moment_left + self.moment_right)
        if self.clamp_start is None:
            return self.t, self.theta, m, self.geometry
        sel = self.t >= self.clamp_start
        return self.t[sel] - self.clamp_start, self.theta[sel], m[sel], self.geometry

    def slip_inputs(self) -> tuple[Array, Array, Array, Array, Array]:
        """``(t, normal_left, tangential_left, normal_right, tangential_right)``, the argument
        order of :func:`estimators.estimate_friction`."""
        forces = (self.normal_left, self.tangential_left, self.normal_right,
                  self.tangential_right)
        if any(f is None for f in forces):
            raise TraceFileError(self.path, "no slip data (normal_left, normal_right, "
                                 "tangential_left, tangential_right)")
        return (self.t, *forces)  # type: ignore[return-value]


@dataclass
class _Table:
    """A parsed file before validation: columns, metadata and how to name a sample's place."""

    columns: dict[str, Array]
    meta: dict[str, float]
    meta_source: dict[str, str]
    where: Callable[[int], str]
    names: tuple[str, ...]  # every column in the file, read or not
    kind: str  # "CSV" or "JSON"
    phases: tuple[str, ...] = PHASES


def load_traces(
    path: str | os.PathLike[str], *, L: float | None = None, theta_0: float | None = None
) -> RecordedTraces:
    """Read and validate recorded traces from a CSV file or ``simulate --json`` output.

    Args:
        path: the file; ``.json`` is read as JSON, ``.csv`` as CSV, any other name by its first
            character (``{`` for JSON).
        L, theta_0: clamp geometry (m, rad); each overrides the file's value.

    Returns:
        A :class:`RecordedTraces`.

    Raises:
        TraceFileError: unreadable or empty file, neither CSV nor JSON, a missing column, a
            non-numeric or NaN/inf value, time not strictly increasing, fewer than
            :data:`MIN_SAMPLES` samples, one half-spoon's trace without the other's, no
            relaxation and no slip data, or clamp geometry neither given nor in the file.
    """
    if not isinstance(path, str | os.PathLike) or isinstance(path, bytes):
        raise EstimationError(f"path must be a file name (str or os.PathLike), got {path!r:.60}")
    L, theta_0 = optional_real("L", L), optional_real("theta_0", theta_0)
    text = _read_text(path)
    if _is_json(path, text):
        table = _parse_json(path, text)
    else:
        table = _parse_csv(path, text)
    t = _check_columns(path, table)
    geometry, geo_source = _geometry(path, table, L, theta_0)
    source = {name: f"column {name!r}" for name in table.columns} | geo_source
    starts: dict[str, float | None] = {}
    for key, phase_name in (("clamp_start", "clamp"), ("slide_start", "slide")):
        starts[key], source[key] = _start(path, table, t, key, phase_name)
    for values in table.columns.values():
        values.setflags(write=False)
    cols = {name: table.columns.get(name) for name in COLUMNS}
    return RecordedTraces(path=os.fspath(path), t=t, theta=cols["theta"],
                          moment_left=cols["moment_left"], moment_right=cols["moment_right"],
                          normal_left=cols["normal_left"], normal_right=cols["normal_right"],
                          tangential_left=cols["tangential_left"],
                          tangential_right=cols["tangential_right"], phase=cols["phase"],
                          geometry=geometry, source=source, phases=table.phases, **starts)


# ----------------------------------------------------------------------------- reading

def _read_text(path: str | os.PathLike[str]) -> str:
    """The file's text; an unreadable, binary or empty file is a :class:`TraceFileError`."""
    try:
        text = Path(path).read_text(encoding="utf-8-sig")
    except OSError as exc:
        raise TraceFileError(path, f"cannot read: {exc.strerror or exc}") from None
    except UnicodeDecodeError:
        raise TraceFileError(path, "not a text file (CSV or JSON expected)") from None
    if not text.strip():
        raise TraceFileError(path, "empty file (CSV or JSON expected)")
    return text


def _is_json(path: str | os.PathLike[str], text: str) -> bool:
    suffix = Path(path).suffix.lower()
    if suffix in (".json", ".csv"):
        return suffix == ".json"
    return text.lstrip()[:1] in ("{", "[")


def _number(path: str | os.PathLike[str], value: object, where: str, text: bool = True) -> float:
    """``value`` (a number, or a CSV cell's text when ``text``) as a float; NaN/inf pass, to be
    reported per column with the sample's place."""
    kinds = (int, float, str) if text else (int, float)
    if isinstance(value, bool) or not isinstance(value, kinds):
        raise TraceFileError(path, f"{where}: {value!r} is not a number")
    try:
        return float(value)
    except OverflowError:  # an integer beyond any float
        raise TraceFileError(path, f"{where}: {str(value)[:20]}... is beyond a float's "
                             "range") from None
    except ValueError:
        shown = repr(value) if str(value).strip() else "empty cell"
        raise TraceFileError(path, f"{where}: {shown} is not a number") from None


def _parse_csv(path: str | os.PathLike[str], text: str) -> _Table:
    """Comment/metadata lines, a header row, then numeric rows (known columns only)."""
    lines = text.splitlines()
    meta: dict[str, float] = {}
    meta_source: dict[str, str] = {}
    i = 0
    while i < len(lines) and (not lines[i].strip() or lines[i].lstrip().startswith("#")):
        key, sep, value = lines[i].lstrip().lstrip("#").partition(":")
        if sep and key.strip() in METADATA_KEYS:
            meta[key.strip()] = _finite_meta(path, key.strip(), value.strip(), f"line {i + 1}")
            meta_source[key.strip()] = f"'# {key.strip()}:' line {i + 1}"
        i += 1
    if i == len(lines):
        raise TraceFileError(path, "no header row (CSV with named columns expected)")
    names = [h.strip() for h in next(csv.reader([lines[i]]))]
    if len(names) < 2:
        raise TraceFileError(path, f"not a CSV file: the header row {lines[i][:40]!r} (line "
                             f"{i + 1}) has no comma-separated column names such as t,theta")
    counts = Counter(names)
    dup = sorted(n for n, c in counts.items() if c > 1 and n in COLUMNS)
    if dup:
        raise TraceFileError(path, f"column {dup[0]!r} appears twice in the header")
    if "t" not in names:
        raise TraceFileError(path, f"missing column 't' (time, s) in the header (line {i + 1}: "
                             f"{', '.join(names)})")
    keep = {n: names.index(n) for n in COLUMNS if n in names}
    rows: dict[str, list[float]] = {n: [] for n in keep}
    line_of: list[int] = []
    for lineno, line in enumerate(lines[i + 1:], start=i + 2):
        if not line.strip():
            continue
        cells = next(csv.reader([line]))
        if len(cells) != len(names):
            raise TraceFileError(path, f"line {lineno} has {len(cells)} cells, the header "
                                 f"has {len(names)}")
        for n, k in keep.items():
            rows[n].append(_number(path, cells[k].strip(), f"line {lineno}, column {n!r}"))
        line_of.append(lineno)
    columns = {n: np.asarray(v, dtype=np.float64) for n, v in rows.items()}
    return _Table(columns, meta, meta_source, lambda j: f"line {line_of[j]}", tuple(names),
                  "CSV")


def _finite_meta(path: str | os.PathLike[str], key: str, value: object, where: str) -> float:
    x = _number(path, value, f"{key} ({where})")
    if not math.isfinite(x):
        raise TraceFileError(path, f"{key} ({where}) is {x}, not a finite number")
    return x


def _parse_json(path: str | os.PathLike[str], text: str) -> _Table:
    """``simulate --json`` output: the traces of its experiment, its geometry and phases."""
    try:
        doc = json.loads(text)
    except json.JSONDecodeError as exc:
        raise TraceFileError(path, f"not valid JSON: {exc.msg} at line {exc.lineno}, column "
                             f"{exc.colno}") from None
    except ValueError as exc:  # an integer literal past Python's digit limit
        raise TraceFileError(path, f"not readable JSON: {str(exc).split(';')[0]}") from None
    except RecursionError:
        raise TraceFileError(path, "not readable JSON: nested too deeply") from None
    if not isinstance(doc, dict) or not isinstance(doc.get("traces"), dict):
        raise TraceFileError(path, "JSON without a 'traces' object (expected what "
                             "'food-fetch simulate --json' writes)")
    experiment = doc.get("experiment")
    if experiment is not None and experiment not in EXPERIMENT_COLUMNS:
        raise TraceFileError(path, f"experiment {experiment!r} has no probe data: record "
                             "'simulate --experiment relaxation' or '--experiment slip'")
    wanted = EXPERIMENT_COLUMNS.get(experiment, COLUMNS)
    traces = doc["traces"]
    columns = {n: _json_column(path, n, traces[n]) for n in wanted if n in traces}
    meta: dict[str, float] = {}
    meta_source: dict[str, str] = {}
    sections = (("geometry", "L", "L"), ("geometry", "theta_0", "theta_0"),
                ("extra", "t_clamp_start", "clamp_start"))
    for section, key, name in sections:
        block = doc.get(section)
        if isinstance(block, dict) and block.get(key) is not None:
            meta[name] = _finite_meta(path, f"{section}.{key}", block[key], "in the file")
            meta_source[name] = f"{section}.{key} in the file"
    phases = doc.get("phases")
    table = _Table(columns, meta, meta_source, lambda j: f"index {j}", tuple(traces), "JSON")
    if isinstance(phases, list) and all(isinstance(p, str) for p in phases):
        table.phases = tuple(phases)
    return table


def _json_column(path: str | os.PathLike[str], name: str, values: Any) -> Array:
    if not isinstance(values, list):
        raise TraceFileError(path, f"traces.{name} is not a list of numbers")
    out = [_number(path, v, f"traces.{name}[{j}]", text=False) for j, v in enumerate(values)]
    return np.asarray(out, dtype=np.float64)


# -------------------------------------------------------------------------- validation

def _check_columns(path: str | os.PathLike[str], table: _Table) -> Array:
    """Check the columns present (one length, finite, ``t`` increasing, enough samples, whole
    probe groups) and return ``t``."""
    cols = table.columns
    found = ", ".join(table.names) or "none"
    if "t" not in cols:
        raise TraceFileError(path, f"missing column 't' (time, s); columns found: {found}")
    t = cols["t"]
    for name, values in cols.items():
        if values.size != t.size:
            raise TraceFileError(path, f"column {name!r} has {values.size} values, 't' has "
                                 f"{t.size}")
        bad = np.flatnonzero(~np.isfinite(values))
        if bad.size:
            raise TraceFileError(path, f"column {name!r} has {values[bad[0]]} at "
                                 f"{table.where(int(bad[0]))} ({bad.size} non-finite value(s))")
        big = np.flatnonzero(np.abs(values) > MAX_SAMPLE)
        if big.size:
            raise TraceFileError(path, f"column {name!r} has {values[big[0]]:g} at "
                                 f"{table.where(int(big[0]))}, beyond +-{MAX_SAMPLE:g} (SI "
                                 "units: s, rad, N, N m)")
    if t.size < MIN_SAMPLES:
        raise TraceFileError(path, f"too short: {t.size} samples, at least {MIN_SAMPLES} "
                             "are needed")
    back = np.flatnonzero(np.diff(t) <= 0.0)
    if back.size:
        j = int(back[0]) + 1
        raise TraceFileError(path, f"time not strictly increasing at {table.where(j)}: "
                             f"t = {float(t[j])!r} s after t = {float(t[j - 1])!r} s")
    fast = np.flatnonzero(np.diff(t) < MIN_SAMPLE_INTERVAL * (1.0 - 1e-6))
    if fast.size:
        j = int(fast[0]) + 1
        raise TraceFileError(path, f"time steps by {float(t[j] - t[j - 1]):.3g} s at "
                             f"{table.where(j)}, below {MIN_SAMPLE_INTERVAL:g} s (a "
                             "megahertz): t must be in seconds")
    _check_groups(path, cols, found)
    return t


def _check_groups(path: str | os.PathLike[str], cols: Mapping[str, Array], found: str) -> None:
    """A probe's columns come whole (both half-spoons), and at least one probe is there."""
    for probe, group in (("relaxation", RELAXATION_COLUMNS), ("slip", SLIP_COLUMNS)):
        have = [c for c in group if c in cols]
        missing = [c for c in group if c not in cols]
        if not have or not missing:
            continue
        for c in missing:
            other = (c.replace("_left", "_right") if c.endswith("_left")
                     else c.replace("_right", "_left"))
            if other != c and other in cols:
                raise TraceFileError(path, f"one half-spoon missing: column {other!r} without "
                                     f"{c!r}")
        raise TraceFileError(path, f"missing column {missing[0]!r}: the {probe} probe needs "
                             f"{', '.join(group)} together (found {', '.join(have)})")
    if not any(c in cols for c in (*RELAXATION_COLUMNS, *SLIP_COLUMNS)):
        raise TraceFileError(path, "no relaxation data (theta, moment_left, moment_right) and "
                             "no slip data (normal_left, normal_right, tangential_left, "
                             f"tangential_right); columns found: {found}")


def _geometry(
    path: str | os.PathLike[str], table: _Table, L: float | None, theta_0: float | None
) -> tuple[ClampGeometry | None, dict[str, str]]:
    """The clamp geometry, each value given or else from the file; needed with relaxation
    data only (the friction estimator does not use it)."""
    given = {"L": L, "theta_0": theta_0}
    values = {k: v if v is not None else table.meta.get(k) for k, v in given.items()}
    source = {k: "given" if given[k] is not None else table.meta_source.get(k, "not given")
              for k in given}
    if "theta" not in table.columns and None in values.values():
        return None, source
    missing = [k for k, v in values.items() if v is None]
    if missing:
        where = {"CSV": "a '# {}: <value>' line", "JSON": "geometry.{} in the JSON"}
        hints = {"L": f"lever arm L [m]: --L or {where[table.kind].format('L')}",
                 "theta_0": f"theta_0 [rad]: --theta-0 or {where[table.kind].format('theta_0')}"}
        raise TraceFileError(path, "clamp geometry missing: " + "; ".join(
            hints[k] for k in missing))
    try:
        geometry = ClampGeometry(L=float(values["L"]), theta_0=float(values["theta_0"]))
    except EstimationError as exc:
        raise TraceFileError(path, f"clamp geometry: {exc}") from None
    return geometry, source


def _start(
    path: str | os.PathLike[str], table: _Table, t: Array, key: str, phase_name: str
) -> tuple[float | None, str]:
    """``clamp_start``/``slide_start``: from the metadata, else the first sample of that phase
    in the ``phase`` column, else None."""
    if key in table.meta:
        value = table.meta[key]
        if not t[0] <= value < t[-1]:
            raise TraceFileError(path, f"{key} = {value!r} s is outside the recorded time "
                                 f"[{float(t[0])!r}, {float(t[-1])!r}) s")
        return value, table.meta_source[key]
    phase = table.columns.get("phase")
    if phase is not None and phase_name in table.phases:
        hit = np.flatnonzero(phase == table.phases.index(phase_name))
        if hit.size:
            return float(t[hit[0]]), f"first '{phase_name}' sample of column 'phase'"
    return None, "not given"
