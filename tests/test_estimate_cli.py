"""``food-fetch estimate`` and ``food-fetch reproduce`` as a user meets them, in a subprocess,
with tiny budgets (short holds and slides): the contract, not the accuracy."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

CMD = [sys.executable, "-m", "agents.cli"]


def run(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([*CMD, *args], capture_output=True, text=True, timeout=300)


def test_estimate_json_contract(tmp_path) -> None:
    out = tmp_path / "e.json"
    p = run(
        "estimate",
        "--omega",
        "0.04",
        "--hold",
        "6",
        "--slide-time",
        "2",
        "--noise",
        "0.01",
        "--json",
        str(out),
    )
    assert p.returncode == 0, p.stderr
    r = json.loads(out.read_text())
    for key in ("true", "estimate", "interval", "r2_clamp", "r2_hold"):
        assert key in r
    names = {"K1", "K2", "B", "g1", "tau1", "mu"}
    assert names <= set(r["true"]) and names <= set(r["estimate"])
    assert r["true"]["g1"] == 0.425 and r["true"]["tau1"] == 3.667
    for k in names:
        assert r["estimate"][k] is not None and r["estimate"][k] > 0, k
        lo, hi = r["interval"][k]
        assert lo <= hi, k
    assert r["true"]["K1"] > 0 and r["true"]["K2"] > 0 and r["true"]["B"] > 0
    assert 0.9 < r["r2_hold"] <= 1.0
    assert "estimate" in p.stdout and "g1" in p.stdout and "mu" in p.stdout
    assert not list(tmp_path.glob("*.part"))


def test_estimate_three_step_slip_only(tmp_path) -> None:
    out = tmp_path / "s.json"
    p = run(
        "estimate",
        "--probe",
        "slip",
        "--slide-time",
        "2",
        "--shape",
        "sphere",
        "--method",
        "three-step",
        "--json",
        str(out),
    )
    assert p.returncode == 0, p.stderr
    r = json.loads(out.read_text())
    assert r["estimate"]["g1"] is None and r["estimate"]["mu"] is not None


@pytest.mark.parametrize(
    ("args", "needle"),
    [
        (["--noise", "2"], "noise"),
        (["--noise", "nan"], "noise"),
        (["--method", "magic"], "method"),
        (["--clamp-weight", "0"], "clamp-weight"),
        (["--probe", "x"], "probe"),
        (["--json", "/no/such/dir/x.json"], "directory"),
        (["--omega", "-1"], "omega"),
        (["--slide-time", "0"], "slide_time"),
        (["--g1", "1.5"], "g1"),
    ],
)
def test_estimate_bad_input_one_line_exit_2(args, needle) -> None:
    p = run("estimate", *args)
    assert p.returncode == 2, (p.stdout, p.stderr)
    lines = p.stderr.strip().splitlines()
    assert len(lines) == 1 and needle in lines[0], p.stderr
    assert "Traceback" not in p.stderr


@pytest.mark.parametrize(
    ("args", "needle"),
    [
        (["reproduce"], "EXPERIMENT"),
        (["reproduce", "nonsense", "--out", "x"], "nonsense"),
        (["reproduce", "friction"], "--out"),
        (["reproduce", "friction", "--out", "/proc/nope"], "nope"),
        (["reproduce", "friction", "--out", "{out}", "--shapes", "pyramid"], "pyramid"),
        (["reproduce", "friction", "--out", "{out}", "--mus", "abc"], "abc"),
        (["reproduce", "viscoelastic", "--out", "{out}", "--omegas", "5"], "omegas"),
        (["reproduce", "viscoelastic", "--out", "{out}", "--hold", "0"], "hold"),
    ],
)
def test_reproduce_bad_input_one_line_exit_2(tmp_path, args, needle) -> None:
    p = run(*[a.replace("{out}", str(tmp_path)) for a in args])
    assert p.returncode == 2, (p.stdout, p.stderr)
    lines = p.stderr.strip().splitlines()
    assert len(lines) == 1 and needle in lines[0], p.stderr


def test_reproduce_names_an_experiment_whose_module_is_missing() -> None:
    """Experiments load lazily (agents/cmd_reproduce.py): a missing module is a usage error
    naming it, not an ImportError.  (This ran through fetch-rate until that module landed,
    and then skipped for good.)"""
    import argparse

    from agents.cli_common import UsageError
    from agents.cmd_reproduce import cmd_reproduce, load

    assert load("no-such-experiment") is None
    with pytest.raises(UsageError, match=r"'no-such-experiment' is not available .*"
                                         r"agents\.reproduce_no_such_experiment"):
        cmd_reproduce(argparse.Namespace(experiment="no-such-experiment"))


def test_reproduce_friction_tiny(tmp_path) -> None:
    p = run(
        "reproduce",
        "friction",
        "--out",
        str(tmp_path),
        "--shapes",
        "cube",
        "--mus",
        "0.3",
        "--slide-time",
        "2",
    )
    assert p.returncode == 0, p.stderr
    for name in ("friction.csv", "friction.md", "friction_by_shape.md", "fig4_friction.png"):
        assert (tmp_path / name).stat().st_size > 0, name
    assert (tmp_path / "fig4_friction.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    md = (tmp_path / "friction.md").read_text()
    assert "0.00400 (1.33 %)" in md  # the study's number beside ours


def test_reproduce_viscoelastic_tiny(tmp_path) -> None:
    p = run(
        "reproduce", "viscoelastic", "--out", str(tmp_path), "--omegas", "0.04,0.03", "--hold", "5"
    )
    assert p.returncode == 0, p.stderr
    for name in (
        "viscoelastic.csv",
        "viscoelastic.md",
        "viscoelastic_trend.md",
        "fig5_fits.png",
        "fig6_parameters.png",
    ):
        assert (tmp_path / name).stat().st_size > 0, name
    assert not list(tmp_path.glob("*.part*"))
