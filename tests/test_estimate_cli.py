"""``food-fetch estimate`` and ``food-fetch reproduce`` as a user meets them, in a subprocess
or in-process, with tiny budgets (short holds and slides): the contract, not the accuracy."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from agents.cli import main
from tests.cli_helpers import assert_one_line_error, run_cli

CMD = [sys.executable, "-m", "agents.cli"]


def run(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([*CMD, *args], capture_output=True, text=True, timeout=300)


def test_estimate_json_contract(tmp_path) -> None:
    out = tmp_path / "e.json"
    p = run("estimate", "--omega", "0.04", "--hold", "6", "--slide-time", "2", "--noise", "0.01",
            "--json", str(out))
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
    # under --probe both the clamp options set the relaxation probe; slip keeps its defaults
    relax, slip = (r["details"][k]["action"] for k in ("relaxation", "slip"))
    assert (relax["theta_d"], relax["omega"], relax["hold"]) == (0.0244, 0.04, 6.0)
    assert (slip["theta_d"], slip["omega"], slip["hold"], slip["slide_time"]) == (
        0.06, 0.1, 0.5, 2.0)


def test_estimate_three_step_slip_only(tmp_path) -> None:
    out = tmp_path / "s.json"
    p = run("estimate", "--probe", "slip", "--slide-time", "2", "--shape", "sphere", "--method",
            "three-step", "--json", str(out))
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


def test_reproduce_friction_tiny(tmp_path) -> None:
    p = run("reproduce", "friction", "--out", str(tmp_path), "--shapes", "cube", "--mus", "0.3",
            "--slide-time", "2")
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


# ------------------------------------------------------------------ in-process, no simulation
@pytest.mark.parametrize(("args", "fragment"), [
    # these apply to the slip probe too (not only its defaults theta_d 0.06, omega 0.1,
    # hold 0.5) and are validated as simulate validates them
    (["--probe", "slip", "--theta-d", "0"], "theta_d must be in (0.0, 0.3] rad, got 0.0"),
    (["--probe", "slip", "--hold", "-3"], "hold must be in [0, 600] s, got -3.0"),
    (["--probe", "slip", "--omega", "99"], "omega must be in [0.001, 2.0] rad/s, got 99.0"),
    (["--probe", "both", "--hold", "601"], "hold must be in [0, 600] s, got 601.0"),
    (["--lift-speed", "0.01"], "--lift-speed 0.01 has no effect here (neither probe lifts"),
    (["--seed", "-1", "--probe", "relaxation", "--hold", "0.5"],
     "--seed: -1 is not in [0, 4294967295]"),
    (["--json", "."], "--json: not a file name: '.'"),
    (["--json", ""], "--json: not a file name: ''"),
], ids=lambda v: v if isinstance(v, str) else " ".join(v))
def test_estimate_mistake_is_one_line_before_any_simulation(
        args: list[str], fragment: str, no_simulation: None,
        capsys: pytest.CaptureFixture[str]) -> None:
    code, out, err = run_cli(["estimate", *args], capsys)
    assert_one_line_error(code, err)
    assert fragment in err and out == "", err


def test_estimate_json_to_a_directory_writes_nothing(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch, no_simulation: None,
        capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.chdir(tmp_path)
    code, _out, err = run_cli(["estimate", "--probe", "slip", "--json", "."], capsys)
    assert_one_line_error(code, err)
    assert list(tmp_path.iterdir()) == []


def test_estimate_slip_probe_uses_the_clamp_options(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    js = tmp_path / "s.json"
    code, _out, err = run_cli(["estimate", "--probe", "slip", "--theta-d", "0.05", "--omega",
                               "0.2", "--hold", "0.2", "--slide-time", "0.5", "--json",
                               str(js)], capsys)
    assert code == 0, err
    action = json.loads(js.read_text())["details"]["slip"]["action"]
    assert (action["theta_d"], action["omega"], action["hold"], action["slide_time"]) == (
        0.05, 0.2, 0.2, 0.5)


def test_estimate_help_states_its_own_defaults(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exc:
        main(["estimate", "--help"])
    assert exc.value.code == 0
    out = " ".join(capsys.readouterr().out.split())  # undo argparse's line wrapping
    assert ("(default: 0.0244 for the relaxation probe, 0.06 for slip, each kept within the "
            "angles that squeeze the piece by 3-12 % (slip 5-25 %) of its half-width past "
            "first contact") in out
    assert "(default: 0.02 for the relaxation probe, 0.1 for slip)" in out
    assert "(default: 25 for the relaxation probe, 0.5 for slip)" in out
    assert "to the relaxation probe only under --probe both" in out
    # simulate's defaults (relaxation hold 15 s, slip theta_d 0.045) and the unused option
    assert "15 for relaxation" not in out and "0.045" not in out and "--lift-speed" not in out


def test_estimate_says_which_probes_and_calibration_it_applied(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """The report names the probes preset, where its contact angle comes from and the
    calibration applied (its form and how many reference foods it was fitted on), in print
    and in the JSON."""
    from fetch_env.probes import PROBE_CALIBRATIONS

    out = tmp_path / "e.json"
    assert main(["estimate", "--probes", "measure", "--shape", "sphere", "--size", "0.012",
                 "--young", "1e6", "--json", str(out)]) == 0
    cal = PROBE_CALIBRATIONS["measure"]
    said = f"{cal.form}, fitted on {cal.n_foods} reference foods"
    printed = capsys.readouterr().out
    line = f"probes: measure (1 relaxation clamp, 1 slide, fit contact angle); calibration: {said}"
    assert line in printed
    assert json.loads(out.read_text())["details"]["settings"]["calibration"] == said


def test_estimate_flags_a_food_stiffer_than_its_calibration_s_reference_foods(
        capsys: pytest.CaptureFixture[str]) -> None:
    """A 40 MPa sphere is estimated, called unreliable, and the report says why (it lies
    beyond the stiffness of the calibration's reference foods), with exit 0: an answer,
    honestly qualified."""
    assert main(["estimate", "--probes", "measure", "--shape", "sphere", "--size", "0.015",
                 "--young", "40e6"]) == 0
    printed = capsys.readouterr().out
    assert "reliable: False" in printed
    assert ("warning: not reliable: this food lies outside the calibration's reference "
            "foods, so its correction and intervals are extrapolated: stiffness per size "
            "24.36 MN/m^2, 2.63 times the reference foods' greatest") in printed
