"""The study's two probes through the whole robot: contacts, hinge servos and sensors.

* Moment relaxation: the food's relaxation must show in the hinge moment as the SLS model
  predicts (the contact and the hinge drive must not act as soft springs in series).
* Induced slippage: the tangential / normal force ratio on the half-spoons during the steady
  slide must be the set mu (Coulomb friction, no creep).
"""

from __future__ import annotations

import numpy as np
import pytest

from estimators import ClampGeometry, SLSParams, moment_trace, steady_moment
from fetch_env import controller
from fetch_env.controller import (
    PHASE_CODE,
    FetchAction,
    FetchSimulator,
    TimeScale,
    relaxation_contact_timeconst,
)
from fetch_env.errors import InvalidParameterError
from fetch_env.layouts import Piece, single_block
from fetch_env.materials import Material
from fetch_env.probes import ProbeConfig, run_probes
from fetch_env.scene import MIN_CONTACT_TIMECONST, Geometry

G1, TAU1 = 0.425, 3.667
THETA_D = 0.0244


def relaxation_overshoot(omega: float, hold: float = 20.0, time_scale: TimeScale | None = None,
                         impratio: float | None = None) -> tuple[float, float]:
    """Measured and SLS-predicted M(t_d) / M_inf - 1 for the study's soft cube."""
    r = FetchSimulator(single_block(), impratio=impratio).run(
        "relaxation", FetchAction(theta_d=THETA_D, omega=omega, hold=hold),
        time_scale=time_scale)
    tr = r.traces
    moment = 0.5 * (tr["moment_left"] + tr["moment_right"])
    clamp = np.flatnonzero(tr["phase"] == PHASE_CODE["clamp"])
    # M(t_d): the last 3 clamp samples (30 ms, well under tau_1) average out contact noise.
    m_peak = moment[clamp[-3:]].mean()
    # M_inf: the last second of the hold, corrected for the exp(-hold / tau_1) still due.
    m_end = moment[tr["t"] > tr["t"][-1] - 1.0].mean()
    residual = np.exp(-(hold - 0.5) / TAU1)
    m_inf = (m_end - residual * m_peak) / (1 - residual)
    # first contact from the trace, as a robot would see it
    theta_1 = tr["theta"][clamp][np.argmax(moment[clamp] > 0.01 * m_peak)]
    geom = ClampGeometry(L=r.geometry["L"], theta_0=r.geometry["theta_0"])
    params = SLSParams.from_prony(1.0, G1, TAU1)
    t_d = THETA_D / omega
    predicted_peak = moment_trace(np.array([t_d]), params, geom, theta_1, THETA_D, omega)[0]
    predicted = predicted_peak / steady_moment(params, geom, theta_1, THETA_D) - 1
    return m_peak / m_inf - 1, predicted


@pytest.mark.parametrize("omega", [0.02, pytest.param(0.01, marks=pytest.mark.slow),
                                   pytest.param(0.03, marks=pytest.mark.slow),
                                   pytest.param(0.04, marks=pytest.mark.slow)])
def test_relaxation_shows_through_the_robot_as_the_sls_predicts(omega: float) -> None:
    measured, predicted = relaxation_overshoot(omega)
    # the study's soft food relaxes by g_1 = 42.5 %: the overshoot is ~0.55-0.7
    assert predicted > 0.5
    np.testing.assert_allclose(measured, predicted, rtol=0.10)


# The env probes' relaxation settings: log-spaced scaled steps and impratio 30 (ProbeConfig).
PROBE_SCALE = TimeScale(ProbeConfig.hold_time_scale, growth=ProbeConfig.hold_time_growth)
PROBE_IMPRATIO = ProbeConfig.relaxation_impratio


@pytest.mark.parametrize(("time_scale", "impratio"), [
    (TimeScale(8.0), None), (PROBE_SCALE, PROBE_IMPRATIO)], ids=["8x", "probe"])
def test_the_time_scaled_hold_relaxes_as_the_sls_predicts(
        time_scale: TimeScale, impratio: float | None) -> None:
    """The same analytic check through a quasi-statically time-scaled hold (8 physical steps a
    step past its first 0.25 s: the 20 s hold then costs 2.7 s of simulated time; or the
    probes' log-spaced steps at their impratio: 0.6 s)."""
    measured, predicted = relaxation_overshoot(0.02, time_scale=time_scale, impratio=impratio)
    np.testing.assert_allclose(measured, predicted, rtol=0.10)


def test_log_spaced_steps_cover_the_hold_exactly() -> None:
    """Each scaled step stands for at least ``factor`` steps and ``growth`` of the elapsed
    hold, at most MAX_TIME_SCALE steps, and together they end the hold on time."""
    dt = 0.005
    steps = TimeScale(8.0, growth=0.05).step_times(0.25, 5.75, dt)
    elapsed = 0.25 + np.concatenate(([0.0], np.cumsum(steps)[:-1]))
    assert steps.sum() == pytest.approx(5.75, abs=1e-12)
    cap = controller.MAX_TIME_SCALE * dt
    np.testing.assert_allclose(steps[:-1], np.minimum(np.maximum(8 * dt, 0.05 * elapsed[:-1]),
                                                      cap), rtol=1e-12)
    assert 0 < steps[-1] <= cap
    # log-spaced: ~ln(6 / 0.25) / ln(1.05) steps past the constant-factor start
    assert 55 <= steps.size <= 75
    assert TimeScale(8.0).step_times(0.25, 5.75, dt).size == 144  # ceil(5.75 / 0.04)


def relaxation_run(pieces: tuple[Piece, ...], hold: float, timestep: float | None = None,
                   time_scale: TimeScale | None = None, impratio: float | None = None,
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """Time, phase, mean blade moment and t_d of the study's clamp (THETA_D at 0.1 rad/s) and
    a relaxation hold (``timestep``, ``impratio`` None: the scene's own)."""
    r = FetchSimulator(pieces, timestep=timestep, impratio=impratio).run(
        "relaxation", FetchAction(theta_d=THETA_D, omega=0.1, hold=hold), time_scale=time_scale)
    tr = r.traces
    t_d = r.extra["t_clamp_start"] + THETA_D / 0.1
    return tr["t"], tr["phase"], 0.5 * (tr["moment_left"] + tr["moment_right"]), t_d


def held_moments(pieces: tuple[Piece, ...], timestep: float | None) -> tuple[float, float]:
    """Mean moment 0.2-0.3 s into a 2 s relaxation hold, and over its last 0.1 s (``timestep``
    None: the scene's own)."""
    t, phase, moment, _ = relaxation_run(pieces, 2.0, timestep)
    hold = phase == PHASE_CODE["hold"]
    t, moment = t[hold], moment[hold]
    start = (t > t[0] + 0.2) & (t < t[0] + 0.3)
    return float(moment[start].mean()), float(moment[-10:].mean())


def study_pieces(soft_rtol: float, stiff_rtol: float) -> pytest.MarkDecorator:
    """Parametrize ``(pieces, moment_rtol)`` over the study's soft cube (fast) and, marked
    slow, its soft sphere and ellipsoid and a 2 MPa cube, each with its bound."""
    slow = pytest.mark.slow
    return pytest.mark.parametrize(("pieces", "moment_rtol"), [
        (single_block(), soft_rtol),
        pytest.param(single_block("sphere"), soft_rtol, marks=slow),
        pytest.param(single_block("ellipsoid"), soft_rtol, marks=slow),
        pytest.param(single_block(material=Material(young=2e6)), stiff_rtol, marks=slow),
    ], ids=["soft-cube", "soft-sphere", "soft-ellipsoid", "2MPa-cube"])


# A 2 MPa cube's held moment is 5.8 % lower at the 5 ms step than at 1.25 ms (measured; 2.4 %
# at 2.5 ms): under MuJoCo's discrete integrator the contact's compliance grows with the step,
# and against a stiff food it is no longer negligible.  Its bound (8 %) records it.
@study_pieces(soft_rtol=0.03, stiff_rtol=0.08)
def test_the_relaxation_through_the_robot_is_converged_in_the_timestep(
        pieces: tuple[Piece, ...], moment_rtol: float) -> None:
    """The default 5 ms step against a quarter of it, on the study's 0.024 rad clamp: the
    held moment (measured within 1.2 / 2.0 / 2.0 % for the 0.2 MPa cube / sphere /
    ellipsoid) and the fraction it relaxes to over the hold (0.6 / 1.5 / 0.8 %; 1.7 % for
    the 2 MPa cube), which is what the estimators read g_1 and tau_1 from."""
    default_step = FetchSimulator(pieces).scene_for("relaxation").model.opt.timestep
    assert default_step == pytest.approx(0.005)  # the step the figures above were measured at
    coarse_start, coarse_end = held_moments(pieces, None)
    fine_start, fine_end = held_moments(pieces, default_step / 4)
    np.testing.assert_allclose(coarse_start, fine_start, rtol=moment_rtol)
    np.testing.assert_allclose(coarse_end, fine_end, rtol=moment_rtol)
    np.testing.assert_allclose(coarse_end / coarse_start, fine_end / fine_start, rtol=0.025)


HOLD_WINDOWS = (0.5, 1.0, 2.0, 4.0, 5.9)  # [s] after t_d


def windowed_hold_moments(pieces: tuple[Piece, ...], time_scale: TimeScale | None,
                          impratio: float | None = None) -> np.ndarray:
    """Mean moment over +-30 ms about each of ``HOLD_WINDOWS`` into a 6 s relaxation hold
    (the study's clamp), in physical time: the mean of the piecewise-linear trace, so that
    a window a long scaled step crosses with no sample in it still has a value."""
    t, _, moment, t_d = relaxation_run(pieces, 6.0, time_scale=time_scale, impratio=impratio)
    offsets = np.linspace(-0.03, 0.03, 13)
    return np.array([np.interp(t_d + w + offsets, t, moment).mean() for w in HOLD_WINDOWS])


@pytest.mark.parametrize(("time_scale", "impratio", "fraction_rtol"), [
    (TimeScale(8.0), None, 0.01), (PROBE_SCALE, PROBE_IMPRATIO, 0.025)], ids=["8x", "probe"])
# the stiff cube's bound (6 %): its held contact chatters and the 5 ms step does not resolve
# it either (above); measured 2.0-4.2 % higher when time-scaled
@study_pieces(soft_rtol=0.025, stiff_rtol=0.06)
def test_the_time_scaled_hold_matches_the_real_time_hold(
        pieces: tuple[Piece, ...], moment_rtol: float, time_scale: TimeScale,
        impratio: float | None, fraction_rtol: float) -> None:
    """A quasi-statically time-scaled hold against the hold simulated in real time at the
    scene's impratio (1000), at the same physical times: the held moment and the fraction it
    relaxes to from 0.5 s to 5.9 s, the shape the estimators read g_1 and tau_1 from.  Wrong
    time bookkeeping moves the fraction by the relaxation itself (~30 %).

    Measured (0.2 MPa cube / sphere / ellipsoid; 2 MPa cube), moments and fraction:
    8 physical steps a step within 1.8 / 0.2 / 0.9 %, fraction 0.1 / 0.2 / 0.2 % (0.5 %);
    the env probes' log-spaced steps at impratio 30 within 1.2 / 0.5 / 1.3 % (2.8 %),
    fraction 1.7 / 0.03 / 2.0 % (1.4 %).  Impratio 30 in real time creeps instead (the
    moment sags up to 5 % below the scaled one by 5.9 s): the scaling leaves creep, a
    mechanical process, no time, which is why the probes can use it."""
    real = windowed_hold_moments(pieces, None)
    scaled = windowed_hold_moments(pieces, time_scale, impratio)
    np.testing.assert_allclose(scaled, real, rtol=moment_rtol)
    np.testing.assert_allclose(scaled[-1] / scaled[0], real[-1] / real[0], rtol=fraction_rtol)


def test_time_scale_is_validated_before_any_physics() -> None:
    with pytest.raises(InvalidParameterError, match="factor"):
        TimeScale(0.5)
    with pytest.raises(InvalidParameterError, match="factor"):
        TimeScale(float("nan"))
    with pytest.raises(InvalidParameterError, match="realtime"):
        TimeScale(8.0, realtime=-1.0)
    with pytest.raises(InvalidParameterError, match="growth"):
        TimeScale(8.0, growth=0.9)
    with pytest.raises(InvalidParameterError, match="impratio"):
        FetchSimulator(single_block(), impratio=0.5)
    with pytest.raises(InvalidParameterError, match="timestep"):
        FetchSimulator(single_block(), timestep=float("nan"))
    with pytest.raises(InvalidParameterError, match="time_scale"):
        FetchSimulator(single_block()).run("slip", FetchAction(), time_scale=TimeScale(8.0))


@pytest.mark.parametrize("mu", [0.1, 0.3, 0.5])
def test_induced_slip_force_ratio_is_coulomb_mu(mu: float) -> None:
    r = FetchSimulator(single_block(material=Material(mu=mu))).run(
        "slip", FetchAction(theta_d=0.045, omega=0.1, hold=0.5, slide_time=10.0))  # 5 mm in 10 s
    tr = r.traces
    slide = np.flatnonzero(tr["phase"] == PHASE_CODE["slide"])
    steady = slide[len(slide) // 4: 3 * len(slide) // 4]  # the middle half of the slide
    normal = tr["normal_left"][steady] + tr["normal_right"][steady]
    tangential = tr["tangential_left"][steady] + tr["tangential_right"][steady]
    assert normal.min() > 1.0  # a real clamp, N
    np.testing.assert_allclose((tangential / normal).mean(), mu, rtol=0.02)
    # and on each half-spoon separately
    for side in ("left", "right"):
        ratio = tr[f"tangential_{side}"][steady] / tr[f"normal_{side}"][steady]
        np.testing.assert_allclose(ratio.mean(), mu, rtol=0.02)


# The probes with a 3 s real-time relaxation hold at the base scene's impratio
# (1000), which the stiff-piece figures below were measured with.  (hold_time_scale=1 alone
# no longer gives it: the scaled steps also grow with the hold, and the
# relaxation probe runs at impratio 30.)
REAL_TIME_PROBES = ProbeConfig(hold=3.0, hold_time_scale=1.0, hold_time_growth=0.0,
                               relaxation_impratio=1000.0)
STIFF_SPHERE = single_block("sphere", 0.0105, Material(young=3.9e6, poisson=0.43, g1=0.416,
                                                       tau1=2.05, mu=0.51))


def hold_relaxation() -> tuple[float, float]:
    """A stiff sphere's reset probe: measured and SLS-predicted M(end) / M(t_d + 0.1 s).

    The piece is held-back seed 90000's (3.9 MPa, 10.5 mm), where the env's g1 estimate
    came out low; the reference is 0.1 s into the hold, past the servo's catch-up.  The
    hold is the 3 s real-time one the figures below were measured with (the env's default
    is now a 6 s time-scaled hold).
    """
    material = STIFF_SPHERE[0].material
    outcome = run_probes(STIFF_SPHERE, REAL_TIME_PROBES, keep_traces=True)
    tr = outcome.traces["relaxation"]
    action = outcome.details["relaxation_action"]
    t = tr["t"] - action["settle"]  # from the clamp start
    moment = 0.5 * (tr["moment_left"] + tr["moment_right"])
    clamp = np.flatnonzero(tr["phase"] == PHASE_CODE["clamp"])
    theta_1 = tr["theta"][clamp][np.argmax(moment[clamp] > 0.01 * moment[clamp].max())]
    t_ref = action["theta_d"] / action["omega"] + 0.1
    ref = int(np.argmin(np.abs(t - t_ref)))
    clamp_geometry = outcome.details["relaxation_geometry"]
    geom = ClampGeometry(L=clamp_geometry["L"], theta_0=clamp_geometry["theta_0"])
    params = SLSParams.from_prony(1.0, material.g1, material.tau1)
    sls = moment_trace(np.array([t[ref], t[-1]]), params, geom, theta_1, action["theta_d"],
                       action["omega"])
    return moment[-1] / moment[ref], sls[1] / sls[0]


def test_contact_is_a_spring_in_series_with_stiff_foods(monkeypatch: pytest.MonkeyPatch) -> None:
    """MuJoCo's contact is a spring in series with the food, whose compliance grows as
    1 / (k m) (k = 1 / timeconst**2, m a node's mass): the relaxation experiment stiffens it
    with the food (``relaxation_contact_timeconst``).

    Against a soft food the default 10 ms contact is stiff (the cube tests above) and is kept;
    against a 3.9 MPa sphere it takes a share of the squeeze, and the moment relaxes far less
    than the material (measured 0.86 of its hold start where the SLS gives 0.70).  The
    stiffened contact (1.9 ms for this piece) brings it within 8 % (measured 0.74).
    """
    assert relaxation_contact_timeconst(STIFF_SPHERE, Geometry()) == pytest.approx(0.0019,
                                                                                   abs=2e-4)
    assert relaxation_contact_timeconst(single_block(), Geometry()) == 0.01  # 0.2 MPa cube
    hard_die = single_block("cube", 0.007, Material(young=2e8))
    assert relaxation_contact_timeconst(hard_die, Geometry()) == MIN_CONTACT_TIMECONST
    stiff_contact, sls = hold_relaxation()
    assert 0.65 < sls < 0.75
    np.testing.assert_allclose(stiff_contact, sls, rtol=0.08)
    # Without the stiffening (the ratio ~0: the geometry's 10 ms contact):
    monkeypatch.setattr(controller, "RELAXATION_CONTACT_RATIO", 1e-12)
    soft_contact, sls_again = hold_relaxation()
    assert sls == pytest.approx(sls_again, rel=0.02)  # the same clamp both times
    assert soft_contact > stiff_contact + 0.08


def test_a_stalled_relaxation_probe_is_estimated_at_the_angle_it_stalled_at() -> None:
    """A stiff cube (sampled seed 5061's: 3.2 MPa, 19.8 mm) stalls the 2 N m motor in the
    reset relaxation probe a little below the last command it was given (the blades' angle
    when the load passed the stall moment).  The estimators must take that stalled angle as
    theta_d (the final command), not the largest command: with the largest one the hold never
    reached theta_d and neither estimator found a hold (measured).

    Run with the real-time 3 s hold the figures were measured with: this stalled stiff cube is
    where the env's default time-scaled hold (6 s, 8x) does worst (g1 +29 %, tau1 +108 %,
    against +21 % / -32 % in real time): its chattering contact creeps, and MuJoCo's
    soft-contact creep is a rate the time scaling does not scale
    (docs/validation/probes.md)."""
    material = Material(young=3212244.0627809814, poisson=0.4377864883888628,
                        density=1106.5149542573067, g1=0.21149751227192837,
                        tau1=2.548873360971311, mu=0.5734666394557012)
    outcome = run_probes(single_block("cube", 0.019779186265348782, material),
                         REAL_TIME_PROBES, keep_traces=True)
    tr = outcome.traces["relaxation"]
    assert tr["theta_cmd"].max() - tr["theta_cmd"][-1] > 1e-5  # stalled below a command
    assert outcome.visco_valid, outcome.warnings
    est = outcome.estimates
    # A stiff cube is the estimators' worst class (contact chatter); measured +20 % / -32 %,
    # and +40 % for g1 with the material rounded to 4 digits: the bar is identification.
    assert 0.5 < est["g1"] / material.g1 < 2.0 and 0.5 < est["tau1"] / material.tau1 < 2.0


def test_drift_diagnostics_are_computed_where_a_calibration_reads_them() -> None:
    """The hold's drift diagnostics (one more fit) are recorded for the "measure" calibration,
    which reads them, and for uncalibrated probes (a calibration may be fitted on them), but
    not for the "env" calibration, which does not; its estimates are the same either way."""
    from fetch_env.probes import PROBE_CALIBRATIONS, PROBE_PRESETS

    pieces = single_block(material=Material(young=2e5, poisson=0.3, density=1000.0, g1=0.4,
                                            tau1=1.5, mu=0.5))
    config = PROBE_PRESETS["env"]
    with_env = run_probes(pieces, config, calibration=PROBE_CALIBRATIONS["env"])
    raw = run_probes(pieces, config)
    assert "drift_log_tau1" not in with_env.details["diagnostics"]
    assert "drift_log_tau1" in raw.details["diagnostics"]
    assert with_env.details["uncalibrated"] == pytest.approx(raw.estimates, rel=1e-12)
    measured = run_probes(pieces, PROBE_PRESETS["measure"],
                          calibration=PROBE_CALIBRATIONS["measure"])
    assert "drift_log_tau1" in measured.details["diagnostics"]
    assert "not calibrated" not in " ".join(measured.warnings)
