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


def assert_help_lists(command: str, options: tuple[str, ...],
                      capsys: pytest.CaptureFixture[str]) -> None:
    """``food-fetch COMMAND --help`` exits 0 and names every one of ``options``."""
    with pytest.raises(SystemExit) as exc:
        main([command, "--help"])
    assert exc.value.code == 0
    out = capsys.readouterr().out
    missing = [opt for opt in options if opt not in out]
    assert missing == []


def interrupt_episode(monkeypatch: pytest.MonkeyPatch, n: int) -> dict[str, int]:
    """Ctrl-C as evaluation starts its ``n``-th episode (the earlier ones run for real);
    the episode counter, which a test may reset."""
    from agents import evaluate as ev

    calls, real = {"n": 0}, ev.run_episode

    def flaky(task: ev.Task) -> dict:
        calls["n"] += 1
        if calls["n"] == n:
            raise KeyboardInterrupt
        return real(task)

    monkeypatch.setattr(ev, "run_episode", flaky)
    return calls
