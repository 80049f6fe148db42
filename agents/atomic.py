"""Files written whole or not at all: a reader never sees half of one.

Every output file is first written to a hidden temporary file in the same folder (same
file system, so the move is atomic) and then moved onto its name with ``os.replace``.  A
failed write (a full disk, a removed folder, an exception) leaves the previous file (or
none) and removes the temporary one; a process killed mid-write leaves at most a hidden
``.NAME.XXXXXXXX.part.EXT``.  Never a truncated ``NAME``.

A path that exists and is not a regular file (a FIFO, a device), and any path under
``/dev`` or ``/proc`` (``/dev/stdout``, ``/dev/full``), is written as it is: it cannot be
replaced, and replacing ``/dev/stdout``'s target would unlink the file the shell redirected
the output to.  Any other symbolic link keeps being a link: its target is replaced.
"""

from __future__ import annotations

import os
import secrets
import shutil
import sys
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager, suppress
from pathlib import Path
from typing import Any

__all__ = ["atomic_path", "write_atomic", "written_as_is"]


_WRITTEN_AS_IS = ("/dev/", "/proc/")


def written_as_is(path: str | os.PathLike[str]) -> bool:
    """Whether ``path`` is written in place rather than replaced (see the module's
    docstring): under /dev or /proc, or an existing file that is not a regular one."""
    p = Path(path)
    return (str(p.absolute()).startswith(_WRITTEN_AS_IS)
            or (p.exists() and not p.is_file()))


def _target(path: Path) -> Path:
    """The file a write to ``path`` changes: a symbolic link's target, else ``path``."""
    return Path(os.path.realpath(path)) if path.is_symlink() else path


def _fsync(path: Path) -> None:
    """Flush ``path``'s data to the disk, so the moved file is whole after a crash too."""
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def _appended(path: Path) -> Iterator[Path]:
    """A temporary file whose bytes are then appended to ``path`` (opened in append mode: a
    shell's ``> out.txt`` behind ``/dev/stdout`` keeps what was printed before)."""
    with tempfile.TemporaryDirectory(prefix="food-fetch-") as folder:
        tmp = Path(folder) / f"out{path.suffix}"
        yield tmp
        stream = _std_stream(path)
        if stream is not None:  # through the process's own stream, in order with its prints
            stream.flush()
            with open(tmp, "rb") as src:
                shutil.copyfileobj(src, stream.buffer)
            stream.flush()
            return
        with open(tmp, "rb") as src, open(path, "ab") as dst:
            shutil.copyfileobj(src, dst)


def _std_stream(path: Path) -> Any:
    """``sys.stdout`` or ``sys.stderr`` when ``path`` is the file behind it (``/dev/stdout``,
    a pipe, a redirected file), else None."""
    try:
        st = os.stat(path)
    except OSError:
        return None
    for stream in (sys.stdout, sys.stderr):
        try:
            fd = os.fstat(stream.fileno())
        except (AttributeError, OSError, ValueError):  # replaced streams (pytest's capture)
            continue
        if (fd.st_dev, fd.st_ino) == (st.st_dev, st.st_ino) and hasattr(stream, "buffer"):
            return stream
    return None


@contextmanager
def atomic_path(path: str | os.PathLike[str]) -> Iterator[Path]:
    """A temporary path beside ``path`` (same folder, same suffix, so writers that pick the
    format from the suffix still work) to write to; moved onto ``path`` when the block ends
    without an error, removed when it raises.  An existing non-regular file is yielded as
    it is (see the module's docstring)."""
    if written_as_is(path):
        yield from _appended(Path(path))
        return
    target = _target(Path(path))
    tmp = target.with_name(f".{target.name}.{secrets.token_hex(4)}.part{target.suffix}")
    try:
        yield tmp
        _fsync(tmp)
        os.replace(tmp, target)
    finally:
        with suppress(OSError):
            tmp.unlink(missing_ok=True)  # gone after os.replace; left over after an error


def write_atomic(path: str | os.PathLike[str], data: str | bytes) -> None:
    """Write ``data`` (text as UTF-8) to ``path`` through a temporary file and
    ``os.replace``; an ``OSError`` (no folder, no space, no permission) leaves ``path`` as
    it was."""
    raw = data.encode("utf-8") if isinstance(data, str) else data
    with atomic_path(path) as tmp, open(tmp, "wb") as fh:
        fh.write(raw)
