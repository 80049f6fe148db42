"""The command as a user meets it, in a subprocess."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

CMD = [sys.executable, "-m", "agents.cli"]


def test_simulate_writes_the_contract(tmp_path) -> None:
    out = tmp_path / "r.json"
    p = subprocess.run([*CMD, "simulate", "--hold", "0.3", "--json", str(out)],
                       capture_output=True, text=True)
    assert p.returncode == 0, p.stderr
    r = json.loads(out.read_text())
    for key in ("fetch_rate", "fetch_rate_mass", "pieces", "material", "geometry", "traces"):
        assert key in r
    assert {"L", "theta_0", "theta_open"} <= set(r["geometry"])
    assert {"young", "poisson", "density", "g1", "tau1", "mu"} <= set(r["material"])
    traces = r["traces"]
    names = ("t", "phase", "theta", "moment_left", "moment_right", "force", "normal_left",
             "tangential_left", "normal_right", "tangential_right")
    lengths = {len(traces[k]) for k in names}
    assert len(lengths) == 1
    assert len(traces["force"][0]) == 3
    dt = traces["t"][1] - traces["t"][0]
    assert dt <= 0.01 + 1e-9  # >= 100 Hz
    assert r["pieces"][0]["fetched"] is True
    assert "fetch rate" in p.stdout


@pytest.mark.parametrize(("args", "needle"), [
    (["--young", "-5"], "young"), (["--poisson", "0.7"], "poisson"), (["--g1", "1.2"], "g1"),
    (["--tau1", "0"], "tau1"), (["--mu", "-1"], "mu"), (["--theta-d", "nan"], "theta-d"),
    (["--shape", "pyramid"], "shape"), (["--json", "/no/such/dir/x.json"], "directory"),
    (["--size", "0.5"], "size"), (["--seed", "-1"], "seed"), (["--json", ""], "file name"),
    (["--json", "."], "file name"), (["--json", "/"], "file name"),
    (["--density", "1e-6"], "density"),
])
def test_user_mistakes_are_one_line_and_exit_2(args: list[str], needle: str) -> None:
    p = subprocess.run([*CMD, "simulate", *args], capture_output=True, text=True)
    assert p.returncode == 2
    lines = p.stderr.strip().splitlines()
    assert len(lines) == 1, p.stderr
    assert needle in lines[0]
    assert "Traceback" not in p.stderr


def test_simulate_says_when_theta_d_was_capped_and_when_a_piece_passed_through(
        tmp_path) -> None:
    """The printout and the JSON say what was actually run: theta_d past the end stop is
    capped there, and a very soft piece squeezed through a blade is flagged, not fetched."""
    p = subprocess.run([*CMD, "simulate", "--theta-d", "0.25", "--hold", "0.2"],
                       capture_output=True, text=True)
    assert p.returncode == 0, p.stderr
    assert "theta_d capped at 0.1767 rad" in p.stdout
    out = tmp_path / "r.json"
    p = subprocess.run([*CMD, "simulate", "--young", "12300", "--theta-d", "0.12", "--omega",
                        "0.4", "--json", str(out)], capture_output=True, text=True)
    assert p.returncode == 0, p.stderr
    assert "PASSED THROUGH" in p.stdout
    r = json.loads(out.read_text())
    assert r["pieces"][0]["passed_through"] is True and r["pieces"][0]["fetched"] is False
    assert r["extra"]["passed_through"] == [0]
    assert r["extra"]["theta_d_applied"] == 0.12 and r["extra"]["stalled_at"] is None


def test_the_core_needs_only_gymnasium_mujoco_numpy_scipy() -> None:
    """The issue's core dependencies, exactly; the rest are extras (pyproject.toml)."""
    import re
    import tomllib
    from pathlib import Path

    project = tomllib.loads((Path(__file__).parents[1] / "pyproject.toml").read_text())["project"]
    names = {re.split(r"[<>=\[ ;]", d, maxsplit=1)[0].lower() for d in project["dependencies"]}
    assert names == {"gymnasium", "mujoco", "numpy", "scipy"}
    from agents.cli.common import EXTRAS

    assert set(EXTRAS) <= set(project["optional-dependencies"])


def test_simulate_and_estimate_import_no_extra() -> None:
    """``food-fetch simulate`` and the core packages run on the core dependencies alone."""
    code = ("import contextlib, io, sys, agents.cli as c; import fetch_env.env, estimators\n"
            "with contextlib.redirect_stdout(io.StringIO()):\n"
            "    assert c.main(['simulate', '--hold', '0.2']) == 0\n"
            "print(sorted(m for m in ('matplotlib', 'tqdm', 'yaml', 'torch', "
            "'stable_baselines3') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout.strip()
    assert out == "[]"


@pytest.mark.parametrize(("args", "extra", "module"), [
    (["reproduce", "friction", "--out", "{tmp}/out"], "figures", "matplotlib"),
    (["evaluate", "--env", "FoodFetch-Block-v0", "--episodes", "1"], "figures", "tqdm"),
    (["train", "--env", "FoodFetch-Block-v0", "--timesteps", "10", "--log-dir",
      "{tmp}/logs"], "train", "stable_baselines3"),
], ids=["reproduce", "evaluate", "train"])
def test_a_missing_extra_is_one_line_and_exit_2_before_any_work(
        tmp_path, monkeypatch, capsys, args: list[str], extra: str, module: str) -> None:
    import importlib.util

    from agents import cli

    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec",
                        lambda name, *a: None if name == module else real(name, *a))
    argv = [a.replace("{tmp}", str(tmp_path)) for a in args]
    assert cli.main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and f"needs the {extra} extra" in err and module in err, err
    assert [p for p in tmp_path.rglob("*") if p.is_file()] == []
