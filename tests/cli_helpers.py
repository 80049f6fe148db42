"""Helpers for the in-process CLI tests: run ``food-fetch`` and check a user mistake's error."""

from __future__ import annotations

import pytest

from agents.cli import main


def run_cli(argv: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, str, str]:
    """``food-fetch argv`` in this process: (exit code, stdout, stderr)."""
    code = main(argv)
    out, err = capsys.readouterr()
    return code, out, err


def assert_one_line_error(code: int, err: str) -> None:
    """A user's mistake: exit code 2 and one line on stderr, no traceback."""
    assert code == 2, err
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err, err
