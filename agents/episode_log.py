"""The episode log of ``food-fetch evaluate``: one JSON line per finished (agent, episode).

The first line is a header holding what decides every episode's numbers (the env id and
kwargs, the first seed, each agent's settings and a model file's SHA-256, the food-fetch
version); each later line is one episode's record, appended and flushed as the episode
finishes, in the order episodes finish.  A run stopped at any moment (Ctrl-C, SIGTERM, a
lost worker, a full disk) keeps every episode that finished before it, and ``evaluate
--resume LOG`` runs only the (agent, episode) tasks the log does not hold yet, after
checking that its header matches the command: episode ``i`` of an agent is the scene of
``reset(seed=seed + i)`` with the agent seeded alike, so a resumed run ends with the same
numbers as an uninterrupted one.

The file is strict JSON Lines (a NaN is written as ``null`` and read back as NaN).  A line
cut short by a stopped run is skipped when read: that episode runs again.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
from pathlib import Path
from typing import IO, Any

from agents.atomic import write_atomic

__all__ = ["FORMAT", "FORMAT_VERSION", "IDENTITY", "EpisodeLog", "LogError", "check_matches",
           "file_digest", "food_fetch_version", "json_safe", "read_log", "restore_record"]

FORMAT = "food-fetch evaluate episodes"
FORMAT_VERSION = 1
# The header's entries that decide an episode's numbers: a resumed run must match them all.
IDENTITY: tuple[str, ...] = ("env", "env_kwargs", "seed", "agents", "agent_settings",
                             "agent_files", "food_fetch_version")
# Record fields that are integers, flags or names; every other number is a float (NaN: null).
_NOT_FLOAT = frozenset({"agent", "episode", "seed", "is_success", "n_pieces", "diverged"})


class LogError(Exception):
    """An episode log that cannot be read or does not match the command (one line)."""


def json_safe(x: Any) -> Any:
    """NaN and infinities as ``None``, so the file is strict JSON (a diverged episode has
    no LE)."""
    if isinstance(x, float):
        return x if math.isfinite(x) else None
    if isinstance(x, dict):
        return {k: json_safe(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [json_safe(v) for v in x]
    return x


def restore_record(rec: dict[str, Any]) -> dict[str, Any]:
    """A record read from JSON with its ``null`` floats back to NaN, as the run made it."""
    return {k: (math.nan if v is None and k not in _NOT_FLOAT else v) for k, v in rec.items()}


def file_digest(path: str | os.PathLike[str]) -> str:
    """SHA-256 of a file (a model agent's zip), so a resumed run uses the same model."""
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def food_fetch_version() -> str:
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("food-fetch")
    except PackageNotFoundError:
        return "unknown"


class EpisodeLog:
    """An open episode log that records are appended to.

    A failed append (no space, a removed folder's file system gone) does not stop the run:
    the log stops taking records, remembers why, and :meth:`problem` says so at the end, when
    the caller writes the results somewhere else.
    """

    def __init__(self, path: Path, fh: IO[str]) -> None:
        self.path = path
        self._fh = fh
        self._error: str | None = None
        self._logged: set[tuple[str, int]] = set()
        try:
            st = os.fstat(fh.fileno())
            self._inode: tuple[int, int] | None = (st.st_dev, st.st_ino)
        except OSError:
            self._inode = None

    @classmethod
    def create(cls, path: Path, header: dict[str, Any]) -> EpisodeLog:
        """A new log holding only ``header`` (an older file of that name is replaced)."""
        line = json.dumps(json_safe({"format": FORMAT, "format_version": FORMAT_VERSION,
                                     **header}), allow_nan=False)
        write_atomic(path, line + "\n")
        return cls(path, open(path, "a", encoding="utf-8"))  # kept open: appended to

    @classmethod
    def reopen(cls, path: Path) -> EpisodeLog:
        """An existing log to append to; a last line cut short is ended first, so the next
        record starts a line of its own (the cut one is skipped when read)."""
        with open(path, "rb") as fh:
            size = fh.seek(0, os.SEEK_END)
            if size:
                fh.seek(-1, os.SEEK_END)
            cut = size > 0 and fh.read(1) != b"\n"
        log = cls(path, open(path, "a", encoding="utf-8"))  # kept open: appended to
        if cut:
            log._write("\n")
        return log

    def _write(self, text: str) -> None:
        if self._error is not None:
            return
        try:
            self._fh.write(text)
            self._fh.flush()
        except OSError as exc:
            self._error = exc.strerror or str(exc)

    def append(self, record: dict[str, Any]) -> None:
        """Append one finished episode's record (its ``transition``, if any, left out)."""
        key = (record["agent"], int(record["episode"]))
        if key in self._logged:
            return
        self._logged.add(key)
        rec = {k: v for k, v in record.items() if k != "transition"}
        self._write(json.dumps(json_safe(rec), allow_nan=False) + "\n")

    def problem(self) -> str | None:
        """Why the log does not hold every appended record at its path, or None."""
        if self._error is not None:
            return self._error
        try:
            st = os.stat(self.path)
        except OSError as exc:
            return f"{exc.strerror or exc} (removed during the run)"
        if self._inode is not None and (st.st_dev, st.st_ino) != self._inode:
            return "replaced by another file during the run"
        return None

    def close(self) -> None:
        try:
            self._fh.close()
        except OSError as exc:  # the last flush failed: the data did not reach the file
            self._error = self._error or exc.strerror or str(exc)


def read_log(path: Path) -> tuple[dict[str, Any], list[dict[str, Any]]]:
    """The header and the records (first of each (agent, episode)) of an episode log."""
    try:
        lines = path.read_text(encoding="utf-8").splitlines()
    except (OSError, UnicodeDecodeError) as exc:
        raise LogError(f"cannot read {str(path)!r}: "
                       f"{getattr(exc, 'strerror', None) or exc}") from None
    try:
        header = json.loads(lines[0]) if lines else None
    except json.JSONDecodeError:
        header = None
    if not isinstance(header, dict) or header.get("format") != FORMAT:
        raise LogError(f"{str(path)!r} is not an episode log of food-fetch evaluate (its "
                       "first line is not the log's header)")
    if header.get("format_version") != FORMAT_VERSION:
        raise LogError(f"{str(path)!r} is an episode log of format version "
                       f"{header.get('format_version')}, this food-fetch reads {FORMAT_VERSION}")
    records: dict[tuple[str, int], dict[str, Any]] = {}
    for line in lines[1:]:
        try:
            rec = json.loads(line)
            key = (str(rec["agent"]), int(rec["episode"]))
        except (json.JSONDecodeError, KeyError, TypeError, ValueError):
            continue  # a line cut short by a stopped run: that episode runs again
        records.setdefault(key, restore_record(rec))
    return header, list(records.values())


def check_matches(path: Path, header: dict[str, Any], expected: dict[str, Any]) -> None:
    """Refuse a log made by a different command: the first entry of :data:`IDENTITY` whose
    value differs, named with both values."""
    for key in IDENTITY:
        theirs, ours = header.get(key), json_safe(expected.get(key))
        if key == "agents":  # the same agents in another order give the same episodes
            theirs, ours = sorted(theirs or []), sorted(ours or [])
        if theirs != ours:
            raise LogError(f"{str(path)!r} was made with {key} {_short(theirs)}, this "
                           f"command has {_short(ours)}: resume with the command that "
                           "started it")


def _short(value: Any, limit: int = 120) -> str:
    text = json.dumps(value, sort_keys=True)
    return text if len(text) <= limit else text[:limit - 3] + "..."
