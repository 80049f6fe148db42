"""Nothing is changed silently: every value the simulator clips, caps or replaces is said.

Each rule of :mod:`fetch_env.clipping` is provoked once and must show up where the caller
looks: the command line's text output, its JSON (``"clipped"``) and ``--help``; an
environment's ``info["clipped"]`` (every time, same for the same seed) and one
:class:`fetch_env.ParameterClippedWarning` per kind and env; and a warning of that category,
located at the caller's line, in the Python API.  A value that is not changed must give no
record and no warning, so the reports cannot be always-on noise.
"""

from __future__ import annotations

import json
import warnings
from pathlib import Path

import numpy as np
import pytest

import fetch_env
from fetch_env import clipping
from fetch_env.controller import FetchAction, FetchSimulator
from fetch_env.env import FoodFetchEnv
from fetch_env.layouts import Piece, single_block
from fetch_env.materials import Material
from fetch_env.scene import simulated_young, young_caps
from fetch_env.spaces import action_to_physical, clip_action, encode_observation
from tests.cli_helpers import run_cli

STIFF = Material(young=2e8)  # above the 9e7 Pa conditioning limit of a 15 mm cube at 5 ms
# 0.78 kg: 156 times the total-mass feature's 5 g scale, beyond the observation's bound of 10
HEAVY = Piece("cube", 0.025, Material(density=5e4))


def _clip_warnings(caught: list[warnings.WarningMessage]) -> list[warnings.WarningMessage]:
    return [w for w in caught if issubclass(w.category, fetch_env.ParameterClippedWarning)]


def test_the_warning_category_is_exported_and_a_user_warning() -> None:
    assert issubclass(fetch_env.ParameterClippedWarning, UserWarning)
    assert "ParameterClippedWarning" in fetch_env.__all__
    assert set(clipping.RULES) == {"young", "action", "theta_d", "end_stop", "hold",
                                   "observation"}


# --------------------------------------------------------------------------------------------
# the command line


def test_simulate_says_in_its_text_and_json_that_9e7_pa_was_simulated(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "r.json"
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        code, text, err = run_cli(["simulate", "--young", "2e8", "--hold", "0.2",
                                   "--json", str(out)], capsys)
    assert code == 0, err
    assert "9e+07 Pa simulated, not 2e+08 Pa" in text
    assert _clip_warnings(caught) == []  # said in the text, not a second time on stderr
    r = json.loads(out.read_text())
    assert [(c["rule"], c["given"], c["applied"]) for c in r["clipped"]] == [
        ("young", 2e8, 9e7)]
    assert r["pieces"][0]["young_simulated"] == 9e7


def test_simulate_reports_nothing_when_nothing_was_changed(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "r.json"
    code, text, err = run_cli(["simulate", "--hold", "0.2", "--json", str(out)], capsys)
    assert code == 0, err
    assert "capped" not in text
    assert json.loads(out.read_text())["clipped"] == []


def test_simulate_reports_the_end_stop_in_its_json(tmp_path: Path,
                                                   capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "r.json"
    code, text, err = run_cli(["simulate", "--theta-d", "0.25", "--hold", "0.2", "--json",
                               str(out)], capsys)
    assert code == 0, err
    assert "theta_d capped at 0.1767 rad" in text
    (rec,) = json.loads(out.read_text())["clipped"]
    assert rec["rule"] == "end_stop" and rec["given"] == 0.25
    assert rec["applied"] == pytest.approx(0.1767, abs=1e-4)


@pytest.mark.parametrize("command", ["simulate", "estimate"])
def test_help_states_the_caps(command: str, capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit):
        run_cli([command, "--help"], capsys)
    text = " ".join(capsys.readouterr().out.split())
    assert "conditioning limit" in text and "9e7 Pa" in text
    assert "end stop" in text


def test_estimate_says_which_modulus_its_probe_simulated(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "e.json"
    code, text, err = run_cli(["estimate", "--probes", "study", "--probe", "slip", "--young",
                               "2e8", "--slide-time", "1", "--json", str(out)], capsys)
    assert code == 0, err
    assert "simulated pieces[0].young 2e+08 -> 9e+07" in text and "slip probe" in text
    (rec,) = json.loads(out.read_text())["clipped"]
    assert (rec["rule"], rec["given"], rec["applied"]) == ("young", 2e8, 9e7)


# --------------------------------------------------------------------------------------------
# the Python API


def test_the_simulator_warns_at_the_caller_s_line() -> None:
    with pytest.warns(fetch_env.ParameterClippedWarning, match=r"young 2e\+08 -> 9e\+07") as rec:
        FetchSimulator((Piece("cube", 0.015, STIFF),)).scene_for("fetch")
    assert rec[0].filename == __file__
    assert simulated_young(Piece("cube", 0.015, STIFF), 0.005) == 9e7
    assert young_caps((Piece("cube", 0.015, Material()),), 0.005) == []


def test_reported_elsewhere_silences_the_simulator() -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with clipping.reported_elsewhere():
            FetchSimulator((Piece("cube", 0.015, STIFF),)).scene_for("fetch")


def test_actions_outside_the_space_warn_in_the_api_and_clip_action_returns_them() -> None:
    with pytest.warns(fetch_env.ParameterClippedWarning, match=r"action\[0\] \(theta_d\) 2"):
        assert action_to_physical([2.0, 0.0, 0.0])["theta_d"] == 0.12
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        a, records = clip_action([2.0, -3.0, 0.5])
        action_to_physical([1.0, -1.0, 0.5])  # inside: no warning
    assert a.tolist() == [1.0, -1.0, 0.5]
    assert [(r["given"], r["applied"]) for r in records] == [(2.0, 1.0), (-3.0, -1.0)]


def test_observation_features_beyond_the_bound_are_reported() -> None:
    from fetch_env.env_scenes import layout_features

    values = {**layout_features((HEAVY,)), "visco_valid": 0.0, "friction_valid": 0.0}
    with pytest.warns(fetch_env.ParameterClippedWarning, match="total_mass"):
        obs = encode_observation(values)
    assert obs.max() == 10.0


# --------------------------------------------------------------------------------------------
# the environments


def _step(env: FoodFetchEnv, action: list[float], **reset: object) -> tuple[dict, dict]:
    _, info0 = env.reset(**reset)  # type: ignore[arg-type]
    _, _, _, _, info = env.step(np.array(action, dtype=np.float32))
    return info0, info


def test_env_reports_every_action_clip_in_info_and_warns_once() -> None:
    env = FoodFetchEnv(estimator="oracle", hold=0.1, air_hold=0.1)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        info0, info1 = _step(env, [1.5, 0.0, 0.0], seed=1)
        _, info2 = _step(env, [0.0, -4.0, 0.0], seed=1)
        _, info3 = _step(env, [0.0, 0.0, 0.0], seed=1)
    assert info0["clipped"] == []
    assert [(c["rule"], c["given"], c["applied"]) for c in info1["clipped"]] == [
        ("action", 1.5, 1.0)]
    assert [(c["name"], c["given"]) for c in info2["clipped"]] == [("action[1] (omega)", -4.0)]
    assert info3["clipped"] == []
    (w,) = _clip_warnings(caught)  # once per env and kind: an SB3 run is not flooded
    assert "action[0] (theta_d) 1.5 -> 1" in str(w.message) and w.filename == __file__
    assert info1["action_applied"]["theta_d"] == 0.12


def test_env_infos_with_clips_stay_equal_for_equal_seeds() -> None:
    a = FoodFetchEnv(estimator="oracle", hold=0.1, air_hold=0.1)
    b = FoodFetchEnv(estimator="oracle", hold=0.1, air_hold=0.1)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", fetch_env.ParameterClippedWarning)
        ia, ib = _step(a, [3.0, 0.0, 0.0], seed=5)[1], _step(b, [3.0, 0.0, 0.0], seed=5)[1]
    assert ia["clipped"] == ib["clipped"] != []


def test_env_reports_a_stiff_user_piece_at_reset_and_step() -> None:
    env = FoodFetchEnv(estimator="oracle", hold=0.1, air_hold=0.1)
    with pytest.warns(fetch_env.ParameterClippedWarning, match=r"pieces\[0\]\.young") as rec:
        info0, info = _step(env, [0.0, 0.0, 0.0],
                            options={"pieces": [Piece("cube", 0.015, STIFF)]})
    assert len(_clip_warnings(list(rec))) == 1  # the fetch scene's, not also the compile's
    assert [(c["rule"], c["applied"]) for c in info0["clipped"]] == [("young", 9e7)]
    assert info["clipped"] == info0["clipped"]  # the step's info carries the reset's


def test_env_reports_the_theta_d_cap_and_the_end_stop_on_a_small_piece() -> None:
    """A 6 mm piece: its blades' tips meet at ~0.089 rad, below theta_d's 0.12 rad top."""
    env = FoodFetchEnv(estimator="oracle", hold=0.1, air_hold=0.1)
    small = single_block(size=0.006, material=Material(young=1e5))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        _, info = _step(env, [1.0, 1.0, 1.0], options={"pieces": small})
    rules = [c["rule"] for c in info["clipped"]]
    assert rules == ["theta_d", "end_stop"]
    cap, stop = info["clipped"]
    assert cap["given"] == 0.12 and cap["applied"] == info["action_applied"]["theta_d"]
    assert stop["applied"] < cap["applied"]
    assert {str(w.message).split(" ")[0] for w in _clip_warnings(caught)} == {"theta_d"}
    assert len(_clip_warnings(caught)) == 2


def test_env_reports_the_settling_hold_capped_at_max_hold() -> None:
    env = FoodFetchEnv(estimator="oracle", lift_at_settling=True, max_hold=0.1)
    with pytest.warns(fetch_env.ParameterClippedWarning, match="max_hold"):
        _, info = env.reset(options={"preset": "block"})
    (rec,) = info["clipped"]
    assert rec["rule"] == "hold" and rec["applied"] == info["hold"] == 0.1
    assert rec["given"] > 1.0  # tau1 ln(g1 / ((1 - g1) tol)) of the study's food: ~7 s


def test_env_reports_a_clipped_observation_feature() -> None:
    env = FoodFetchEnv(estimator="none")
    with pytest.warns(fetch_env.ParameterClippedWarning, match="total_mass"):
        obs, info = env.reset(options={"pieces": [HEAVY]})
    (rec,) = info["clipped"]
    assert rec["rule"] == "observation" and rec["given"] == pytest.approx(HEAVY.mass)
    assert rec["applied"] == pytest.approx(0.05)  # 10 x the 5 g scale
    assert float(obs.max()) == 10.0


def test_sampled_stiff_dice_warn_once_per_env_and_are_always_in_info() -> None:
    env = FoodFetchEnv(layout="diced", estimator="oracle")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        infos = [env.reset(seed=s)[1] for s in range(4)]
    young = [c for i in infos for c in i["clipped"] if c["rule"] == "young"]
    assert young, "the diced scenes hold 200 MPa dice, above the conditioning limit"
    assert len(_clip_warnings(caught)) == 1


def test_fetch_action_is_not_capped_by_the_api() -> None:
    """FetchAction refuses out-of-range values instead of changing them."""
    with pytest.raises(fetch_env.InvalidParameterError, match="theta_d"):
        FetchAction(theta_d=0.5)
