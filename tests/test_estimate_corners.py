"""``food-fetch estimate`` at the corners of the food space: an answer or one line, never a
traceback (the probes' angles adapt to the piece's size and shape)."""

from __future__ import annotations

import math

import pytest

from fetch_env.food_space import Food, corner_foods
from tests.cli_helpers import assert_one_line_error, run_cli

CORNERS = corner_foods()
# The default run takes three corners that failed before the angles adapted (a 25 mm soft
# sphere the study's angle never reaches, a 25 mm stiff cube, an 8 mm stiff ellipsoid);
# the slow run takes all 24.
QUICK = [f for f in CORNERS if (f.shape, f.size, f.young, f.g1) in {
    ("sphere", 0.025, 0.0123e6, 0.8), ("cube", 0.025, 5e6, 0.1), ("ellipsoid", 0.008, 5e6, 0.8)}]


def _argv(f: Food, probes: str) -> list[str]:
    study = {"study": ["--probes", "study", "--hold", "8"], "repeated": ["--probes", "repeated"],
             "precise": []}[probes]  # precise: the default
    return ["estimate", "--shape", f.shape, "--size", repr(f.size), "--young", repr(f.young),
            "--g1", repr(f.g1), "--tau1", repr(f.tau1), "--mu", repr(f.mu), *study]


def _check(f: Food, capsys: pytest.CaptureFixture[str], probes: str) -> None:
    code, out, err = run_cli(_argv(f, probes), capsys)  # an escaping exception fails it
    if code == 2:
        assert_one_line_error(code, err)
        return
    assert code == 0 and "Traceback" not in out + err
    rows = {line.split()[0]: line.split() for line in out.splitlines() if line[:2] in
            ("g1", "ta", "mu")}
    assert {"g1", "tau1", "mu"} <= set(rows)
    # every estimate found, or its reason printed
    for name in ("g1", "tau1", "mu"):
        value = rows[name][2]
        assert value != "-" or "warning:" in out, (name, out)
        if value != "-":
            assert math.isfinite(float(value)) and float(value) > 0


@pytest.mark.parametrize("probes", ["precise", "study"])
@pytest.mark.parametrize("food", QUICK, ids=lambda f: f"{f.shape}-{f.size}-{f.young:g}")
def test_estimate_answers_at_hard_corners(food: Food, probes: str,
                                          capsys: pytest.CaptureFixture[str]) -> None:
    assert len(QUICK) == 3
    _check(food, capsys, probes)


@pytest.mark.slow
@pytest.mark.parametrize("probes", ["precise", "repeated", "study"])
@pytest.mark.parametrize("food", CORNERS, ids=lambda f: f"{f.shape}-{f.size}-{f.young:g}-{f.g1}")
def test_estimate_answers_at_every_corner(food: Food, probes: str,
                                          capsys: pytest.CaptureFixture[str]) -> None:
    _check(food, capsys, probes)
