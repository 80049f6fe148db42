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
    (["--size", "0.5"], "size"),
])
def test_user_mistakes_are_one_line_and_exit_2(args: list[str], needle: str) -> None:
    p = subprocess.run([*CMD, "simulate", *args], capture_output=True, text=True)
    assert p.returncode == 2
    lines = p.stderr.strip().splitlines()
    assert len(lines) == 1, p.stderr
    assert needle in lines[0]
    assert "Traceback" not in p.stderr
