"""``food-fetch reproduce`` as a user meets it: every option is checked before ``--out`` is
created or a progress bar starts, and a failed call leaves no directory behind."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import pytest

from tests.cli_helpers import assert_one_line_error, run_cli


@pytest.mark.parametrize(("argv", "fragment"), [
    (["friction", "--shapes", "cylinder"], "unknown shapes 'cylinder'"),
    (["friction", "--mus", "0"], "--mus values must be in (0, 2], got 0"),
    (["friction", "--noise", "2"], "--noise must be in [0, 0.5], got 2"),
    (["friction", "--seed", "abc"], "--seed: not an integer: 'abc'"),
    # checked before the tqdm bar starts (else two stderr lines)
    (["friction", "--slide-time", "0"], "--slide-time must be in (0, 120] s, got 0"),
    (["viscoelastic", "--hold", "0.1"], "--hold must be in [0.5, 600] s, got 0.1"),
    (["viscoelastic", "--clamp-weight", "0"], "--clamp-weight must be in (0, 1e6], got 0"),
    (["viscoelastic", "--seed", "-5", "--omegas", "0.04", "--hold", "0.5"],
     "--seed: -5 is not in [0, 4294967295]"),
    (["fetch-rate", "--seed", "-1", "--quick", "--no-figures"],
     "--seed: -1 is not in [0, 4294967295]"),
    (["fetch-rate", "--seed", str(2**32)], f"--seed: {2**32} is not in [0, 4294967295]"),
    (["friction", "--out", " "], "--out: not a directory name: ' '"),
    (["friction", "--mus", "0.1,,0.2"], "--mus '0.1,,0.2' has an empty item"),
], ids=lambda v: v if isinstance(v, str) else " ".join(v))
def test_a_mistake_is_one_line_and_creates_no_out_dir(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], no_simulation: None,
        argv: list[str], fragment: str) -> None:
    out = tmp_path / "new" / "out"
    code, _out, err = run_cli(["reproduce", argv[0], "--out", str(out), *argv[1:]], capsys)
    assert_one_line_error(code, err)
    assert fragment in err and "%|" not in err, err  # "%|": a tqdm bar
    assert not (tmp_path / "new").exists()


def test_a_missing_figures_extra_creates_no_out_dir(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec",
                        lambda name, *a: None if name == "matplotlib" else real(name, *a))
    code, _out, err = run_cli(["reproduce", "friction", "--out", str(tmp_path / "out")], capsys)
    assert_one_line_error(code, err)
    assert "needs the figures extra" in err
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize(("out", "fragment"), [
    ("file", "--out: not a directory"),
    ("file/sub", "--out: cannot create"),
])
def test_an_out_that_cannot_be_a_directory_is_one_line(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], out: str, fragment: str) -> None:
    (tmp_path / "file").write_text("x")
    code, _out, err = run_cli(["reproduce", "friction", "--out", str(tmp_path / out)], capsys)
    assert_one_line_error(code, err)
    assert fragment in err


@pytest.mark.parametrize("exists", [False, True], ids=["new", "existing"])
def test_a_failed_run_removes_only_the_empty_dir_it_created(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str],
        exists: bool) -> None:
    import dataclasses

    from agents.cli import reproduce

    def interrupted(**_kwargs: object) -> int:
        raise KeyboardInterrupt

    monkeypatch.setitem(reproduce.EXPERIMENTS, "friction",
                        dataclasses.replace(reproduce.EXPERIMENTS["friction"], run=interrupted))
    out = tmp_path / "new" / "out"
    if exists:
        out.mkdir(parents=True)
    code, _out, err = run_cli(["reproduce", "friction", "--out", str(out)], capsys)
    assert code == 130, err
    assert (tmp_path / "new").exists() == exists  # a user's folder is never removed


def test_out_is_created_once_the_inputs_are_good(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "new" / "out"
    code, _out, err = run_cli(["reproduce", "friction", "--out", str(out), "--shapes", "cube",
                               "--mus", "0.3", "--slide-time", "1"], capsys)
    assert code == 0, err
    assert (out / "friction.md").stat().st_size > 0
    assert (out / "fig4_friction.png").stat().st_size > 0
