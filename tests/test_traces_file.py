"""``food-fetch estimate --traces FILE`` and :func:`estimators.load_traces`: recorded traces
(CSV, or ``simulate --json`` output) give exactly what the estimators give on the same traces,
and every kind of bad file is one typed error / one line on stderr with exit code 2."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest
from numpy.testing import assert_allclose

from agents.cli.estimate import NAMES
from agents.cli.traces import (
    SlipReading,
    estimate_recorded,
    settle_samples,
    slide_samples,
)
from estimators import (
    ClampGeometry,
    EstimationError,
    SLSParams,
    TraceFileError,
    estimate_friction,
    estimate_full_fit,
    estimate_three_step,
    load_traces,
    moment_trace,
)
from estimators.slip_level import read_mu
from estimators.sls import clamp_angle
from estimators.trace_files import MIN_SAMPLES, PHASES
from fetch_env.study_probes import SIM_CLAMP_WEIGHT, relaxation_traces
from tests.cli_helpers import assert_one_line_error, run_cli

RELAX_KEYS = ("K1", "K2", "B", "g1", "tau1")
FORCES = ("normal_left", "tangential_left", "normal_right", "tangential_right")
MU = 0.3  # the synthetic slides' friction coefficient


# ------------------------------------------------------------------------------- helpers

def write_csv(path: Path, columns: dict[str, Any], meta: dict[str, float] | None = None) -> Path:
    """A traces CSV: ``# key: value`` lines, a header, rows of exactly round-tripping floats."""
    lines = [f"# {k}: {v!r}" for k, v in (meta or {}).items()]
    lines.append(",".join(columns))
    values = [np.asarray(v, dtype=np.float64) for v in columns.values()]
    lines += [",".join(repr(float(v[i])) for v in values) for i in range(values[0].size)]
    path.write_text("\n".join(lines) + "\n")
    return path


def estimate_json(path: Path, capsys: pytest.CaptureFixture[str], *extra: str) -> dict[str, Any]:
    """``food-fetch estimate --traces PATH --json`` in this process: the JSON written."""
    out = path.with_name(path.name + ".estimate.json")
    code, stdout, err = run_cli(["estimate", "--traces", str(path), "--json", str(out), *extra],
                                capsys)
    assert code == 0, err
    assert "Traceback" not in err
    assert stdout.splitlines()[0].startswith(f"recorded traces {path}")
    return json.loads(out.read_text())


def sim_relaxation(doc: dict[str, Any]) -> tuple[np.ndarray, np.ndarray, np.ndarray, Any]:
    """``(t, theta, M, geometry)`` as the simulated ``estimate`` path builds them."""
    result = SimpleNamespace(traces={k: np.asarray(v) for k, v in doc["traces"].items()},
                             extra=doc["extra"], geometry=doc["geometry"])
    return relaxation_traces(result)


def synthetic_relaxation(n: int = 400, uniform: bool = True) -> dict[str, np.ndarray]:
    """An exact SLS clamp-and-hold (0.5 s at rest, then 0.02 rad/s to 0.024 rad, hold)."""
    rng = np.random.default_rng(3)
    t = np.linspace(0.0, 8.0, n) if uniform else np.sort(rng.uniform(0.0, 8.0, n))
    geom = ClampGeometry(L=0.04, theta_0=0.0)
    m = moment_trace(t, SLSParams(4000.0, 2000.0, 6000.0), geom, 0.005, 0.024, 0.02, 0.5)
    return {"t": t, "theta": clamp_angle(t, 0.024, 0.02, 0.5), "moment_left": m,
            "moment_right": m.copy()}


# -------------------------------------------------------------------------- round trips

@pytest.fixture(scope="module")
def sim_docs(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """One short relaxation and one slip run written by ``simulate --json``."""
    from agents.cli import main

    tmp = tmp_path_factory.mktemp("sim")
    out = {}
    for experiment, extra in (("relaxation", ["--hold", "2"]), ("slip", [])):
        out[experiment] = tmp / f"{experiment}.json"
        assert main(["simulate", "--experiment", experiment, "--json",
                     str(out[experiment]), *extra]) == 0
    return out


@pytest.mark.parametrize("method", ["full", "three-step"])
def test_relaxation_round_trip_json_and_csv(
    sim_docs: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str], method: str
) -> None:
    doc = json.loads(sim_docs["relaxation"].read_text())
    t, theta, m, geom = sim_relaxation(doc)
    if method == "full":
        direct = estimate_full_fit(t, theta, m, geom, clamp_weight=SIM_CLAMP_WEIGHT)
    else:
        direct = estimate_three_step(t, theta, m, geom)
    tr = doc["traces"]
    csv_path = write_csv(
        tmp_path / "relaxation.csv",
        {k: tr[k] for k in ("t", "theta", "moment_left", "moment_right", "phase")},
        {"L": doc["geometry"]["L"], "theta_0": doc["geometry"]["theta_0"],
         "clamp_start": doc["extra"]["t_clamp_start"]},
    )
    for path in (sim_docs["relaxation"], csv_path):
        r = estimate_json(path, capsys, "--method", method)
        for k in RELAX_KEYS:
            assert_allclose(r["estimate"][k], getattr(direct, k), rtol=1e-9, err_msg=k)
        assert set(r["interval"]) == set(direct.intervals) & set(NAMES)
        for k in r["interval"]:
            assert_allclose(r["interval"][k], direct.intervals[k], rtol=1e-9, err_msg=k)
        assert_allclose([r["r2_clamp"], r["r2_hold"]], [direct.r2_clamp, direct.r2_hold],
                        rtol=1e-9)
        assert r["estimate"]["mu"] is None  # a relaxation run has no slide
        assert all(v is None for v in r["true"].values()) and set(r["true"]) == set(NAMES)
        assert r["reliable"] == direct.reliable


def test_a_known_contact_angle_is_the_full_fits(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """``--contact-angle`` (a depth camera's) is the full fit's first-contact angle, not
    fitted: on an exact SLS trace touched at 0.005 rad the estimate is the truth (K1 4000,
    K2 2000, B 6000 N/m, N s/m) to 1e-6 and exactly ``estimate_full_fit(..., theta_1=)``'s;
    the JSON's settings say what was given."""
    cols = synthetic_relaxation()
    path = write_csv(tmp_path / "known.csv", cols, {"L": 0.04, "theta_0": 0.0})
    r = estimate_json(path, capsys, "--contact-angle", "0.005")
    t, theta = cols["t"], cols["theta"]
    direct = estimate_full_fit(t, theta, cols["moment_left"], ClampGeometry(L=0.04, theta_0=0.0),
                               clamp_weight=SIM_CLAMP_WEIGHT, theta_1=0.005)
    assert direct.theta_1 == 0.005 and r["details"]["relaxation"]["theta_1"] == 0.005
    for k, true in (("K1", 4000.0), ("K2", 2000.0), ("B", 6000.0)):
        assert_allclose(r["estimate"][k], getattr(direct, k), rtol=1e-9, err_msg=k)
        assert_allclose(r["estimate"][k], true, rtol=1e-6, err_msg=k)
    assert r["details"]["settings"]["contact_angle"] == 0.005
    with pytest.raises(EstimationError, match=r"theta_1=0.03 rad must be in \[0, theta_d"):
        estimate_full_fit(t, theta, cols["moment_left"], ClampGeometry(L=0.04, theta_0=0.0),
                          theta_1=0.03)


def _probe_reading(tr: dict[str, np.ndarray]) -> tuple[float, list[str], tuple[float, float]]:
    """mu as the simulated slip probe reads the run ``tr`` (its phases mark the slide and
    the settle before the blades touch)."""
    phase = tr["phase"]
    return read_mu(tr["t"], {k: tr[k] for k in FORCES}, phase == PHASES.index("slide"),
                   phase == PHASES.index("settle"), "per_blade_simex")


def test_slip_round_trip_json_and_csv(
    sim_docs: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The default reading is the simulated probes' (``read_mu``) and ``--mu-reading
    study`` the study's estimator, on the JSON and on the CSV made from it alike."""
    doc = json.loads(sim_docs["slip"].read_text())
    tr = {k: np.asarray(v) for k, v in doc["traces"].items()}
    slide_start = float(tr["t"][tr["phase"] == PHASES.index("slide")][0])
    direct = estimate_friction(tr["t"], *(tr[k] for k in FORCES), slide_start=slide_start)
    probe_mu, _, probe_interval = _probe_reading(tr)
    # no slide_start line: the CSV's phase column gives it, as the JSON's does
    csv_path = write_csv(tmp_path / "slip.csv", {k: tr[k] for k in ("t", *FORCES, "phase")})
    for path in (sim_docs["slip"], csv_path):
        r = estimate_json(path, capsys)
        assert r["estimate"]["mu"] == probe_mu and r["interval"]["mu"] == list(probe_interval)
        assert r["details"]["slip"]["reading"] == "slipping"
        assert r["details"]["settings"]["mu_reading"] == "slipping"
        assert all(r["estimate"][k] is None for k in RELAX_KEYS)  # slip data only
        assert r["details"]["settings"]["source"]["slide_start"].startswith("first 'slide'")
        r = estimate_json(path, capsys, "--mu-reading", "study")
        assert_allclose(r["estimate"]["mu"], direct.mu, rtol=1e-9)
        assert_allclose(r["interval"]["mu"], direct.interval, rtol=1e-9)
        assert r["details"]["slip"]["window"] == list(direct.window)
        assert r["details"]["slip"]["reading"] == "study"
    assert_allclose(probe_mu, 0.3, rtol=0.01)  # the default cube's mu


def test_a_noisy_stick_slip_log_is_read_at_its_slipping_level(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A robot's CSV of a stick-slipping slide with 1 % sensor noise and no phase column
    (``clamp_start`` and ``slide_start`` lines mark it): the default reading is the one the
    simulated probe takes of the same forces and lands within 1.5 % of mu; the study's
    plateau reads the sticking level, over 10 % low, with an interval that misses mu."""
    n_settle = 30
    cols = _stick_slip_log(n_settle=n_settle)
    t = cols["t"]
    noisy = {k: cols[k] for k in FORCES}
    slide_start = float(t[n_settle])
    path = write_csv(tmp_path / "robot_slip.csv", cols,
                     meta={"clamp_start": float(t[n_settle - 1]), "slide_start": slide_start})
    r = estimate_json(path, capsys)
    expected = read_mu(t, noisy, t >= slide_start, t < t[n_settle - 1], "per_blade_simex")
    assert r["estimate"]["mu"] == expected[0]
    assert_allclose(r["estimate"]["mu"], MU, rtol=0.015)
    lo, hi = r["interval"]["mu"]
    assert lo <= MU <= hi
    study = estimate_json(path, capsys, "--mu-reading", "study")
    assert study["estimate"]["mu"] < 0.9 * MU
    lo, hi = study["interval"]["mu"]
    assert not lo <= MU <= hi


def _stick_slip_log(n_settle: int = 30, n_slide: int = 200, n_after: int = 0,
                    noise: float = 0.01) -> dict[str, np.ndarray]:
    """A stick-slipping slide (3 samples in 10 at mu, the rest at 0.7 mu) after ``n_settle``
    samples before contact and before ``n_after`` samples of release (forces zero), with
    white noise of ``noise`` of each force's peak; 5 ms samples."""
    rng = np.random.default_rng(11)
    ratio = np.where(np.arange(n_slide) % 10 < 3, MU, 0.7 * MU)
    t = 0.005 * np.arange(n_settle + n_slide + n_after)
    cols: dict[str, np.ndarray] = {"t": t}
    for side, press in (("left", 1.0), ("right", 1.2)):
        normal = np.r_[np.zeros(n_settle), np.full(n_slide, press), np.zeros(n_after)]
        cols[f"normal_{side}"] = normal
        cols[f"tangential_{side}"] = normal * np.r_[np.zeros(n_settle), ratio,
                                                    np.zeros(n_after)]
    for k in FORCES:
        cols[k] = cols[k] + noise * float(np.abs(cols[k]).max()) * rng.standard_normal(t.size)
    return cols


def test_the_slide_and_the_samples_before_contact_from_phases_and_metadata(
        tmp_path: Path) -> None:
    """The slide is phase ``slide`` from ``slide_start`` on (samples after it are a release,
    not the slide); the noise is read from phase ``settle`` and from the samples before
    ``clamp_start`` alike; a phase column without a slide, and no ``slide_start``, marks
    none."""
    cols = _stick_slip_log(n_settle=30, n_slide=200, n_after=40)
    t = cols["t"]
    phase = np.r_[np.full(30, PHASES.index("clamp")), np.full(200, PHASES.index("slide")),
                  np.full(40, PHASES.index("hold"))]
    # no settle code: the samples before clamp_start are the ones before contact
    traces = load_traces(write_csv(tmp_path / "a.csv", {**cols, "phase": phase},
                                   meta={"clamp_start": float(t[30]),
                                         "slide_start": float(t[50])}))
    slide = slide_samples(traces)
    assert slide is not None and int(slide.sum()) == 180 and not slide[230:].any()
    settle = settle_samples(traces)
    assert settle is not None and int(settle.sum()) == 30
    got = estimate_recorded(traces)
    assert isinstance(got.friction, SlipReading)
    assert not any("before the blades touch" in w for w in got.friction.warnings)
    assert_allclose(got.friction.mu, MU, rtol=0.015)
    no_slide = np.where(phase == PHASES.index("slide"), PHASES.index("hold"), phase)
    traces = load_traces(write_csv(tmp_path / "b.csv", {**cols, "phase": no_slide}))
    assert slide_samples(traces) is None and settle_samples(traces) is not None
    got = estimate_recorded(traces)
    assert got.notes and "marks no slide" in got.notes[0] and not got.friction.reliable


@pytest.mark.parametrize(("slide", "settle", "fragment"), [
    (np.ones(10, dtype=int), None, "slide must be a boolean array"),
    (np.ones(9, dtype=bool), None, "slide must be a boolean array"),
    (np.ones(10, dtype=bool), [True] * 10, "settle must be a boolean array"),
])
def test_read_mu_refuses_masks_that_are_not_one_boolean_a_sample(
        slide: Any, settle: Any, fragment: str) -> None:
    t = np.arange(10.0)
    with pytest.raises(EstimationError, match=fragment):
        read_mu(t, {k: np.ones(10) for k in FORCES}, slide, settle)
    with pytest.raises(EstimationError, match="missing normal_left"):
        read_mu(t, {}, np.ones(10, dtype=bool), None)
    short = {k: np.ones(10 if k != "tangential_right" else 9) for k in FORCES}
    with pytest.raises(EstimationError, match="trace 'tangential_right' has 9 samples"):
        read_mu(t, short, np.ones(10, dtype=bool), None)


def test_a_recorded_slide_is_never_called_reliable(tmp_path: Path) -> None:
    """Its interval holds the probes' systematic 2 % of mu (log sd), at least +-4 % wide,
    and the uncalibrated rule is +-2.5 %; even a noise-free steady slide is not reliable."""
    cols = _stick_slip_log(noise=0.0)
    steady = {k: (v if not k.startswith("tangential") else
                  np.where(cols[k.replace("tangential", "normal")] > 0,
                           MU * cols[k.replace("tangential", "normal")], 0.0))
              for k, v in cols.items()}
    traces = load_traces(write_csv(tmp_path / "steady.csv", steady,
                                   meta={"clamp_start": float(cols["t"][30]),
                                         "slide_start": float(cols["t"][30])}))
    got = estimate_recorded(traces).friction
    assert isinstance(got, SlipReading)
    assert_allclose(got.mu, MU, rtol=1e-9)
    lo, hi = got.interval
    assert min(hi / got.mu - 1, 1 - lo / got.mu) >= 0.038 and not got.reliable


def test_a_slide_the_file_does_not_mark_is_read_by_the_study_estimator(
    tmp_path: Path, sim_docs: dict[str, Path], capsys: pytest.CaptureFixture[str]
) -> None:
    """Without a phase column or ``slide_start`` the slipping level has no slide to read:
    the study's estimator, which finds the slide itself, reads it, and the report says so."""
    doc = json.loads(sim_docs["slip"].read_text())
    tr = {k: np.asarray(v) for k, v in doc["traces"].items()}
    path = write_csv(tmp_path / "unmarked.csv", {k: tr[k] for k in ("t", *FORCES)})
    r = estimate_json(path, capsys)
    direct = estimate_friction(tr["t"], *(tr[k] for k in FORCES))
    assert r["estimate"]["mu"] == direct.mu and r["details"]["slip"]["reading"] == "study"
    assert any("the file marks no slide" in w for w in r["warnings"])


def test_report_shows_unknown_truth_as_dash(
    sim_docs: dict[str, Path], capsys: pytest.CaptureFixture[str]
) -> None:
    code, out, err = run_cli(["estimate", "--traces", str(sim_docs["relaxation"])], capsys)
    assert code == 0, err
    rows = {line.split()[0]: line.split() for line in out.splitlines()[2:8]}
    assert set(rows) == set(NAMES)
    assert all(rows[k][1] == "-" and rows[k][3] == "-" for k in NAMES)  # true, error
    assert rows["K1"][2] != "-" and rows["mu"][2] == "-"


def test_estimate_recorded_is_the_estimators(sim_docs: dict[str, Path]) -> None:
    """The Python path: load_traces + estimate_recorded, against the estimator calls."""
    traces = load_traces(sim_docs["slip"])
    assert traces.probes == ("slip",) and traces.clamp_start == 0.3
    got = estimate_recorded(traces)
    assert isinstance(got.friction, SlipReading) and got.relaxation is None
    assert not got.failures and not got.notes
    tr = {k: np.asarray(v) for k, v in json.loads(sim_docs["slip"].read_text())[
        "traces"].items()}
    assert got.friction.mu == _probe_reading(tr)[0]
    study = estimate_recorded(traces, mu_reading="study")
    direct = estimate_friction(*traces.slip_inputs(), slide_start=traces.slide_start)
    assert study.friction is not None and study.friction.mu == direct.mu
    with pytest.raises(TraceFileError, match="no relaxation data"):
        estimate_recorded(traces, probe="relaxation")
    with pytest.raises(ValueError, match="mu_reading must be one of"):
        estimate_recorded(traces, mu_reading="plateau")


def test_real_robot_csv_non_uniform_geometry_given(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A log without metadata and with uneven sampling: geometry from the options, and the
    exact SLS trace gives back its K1, K2, B."""
    path = write_csv(tmp_path / "robot.csv", synthetic_relaxation(uniform=False))
    traces = load_traces(path, L=0.04, theta_0=0.0)
    assert traces.source["L"] == "given" and traces.clamp_start is None
    assert not traces.t.flags.writeable
    r = estimate_json(path, capsys, "--L", "0.04", "--theta-0", "0")
    assert_allclose([r["estimate"][k] for k in ("K1", "K2", "B")], [4000.0, 2000.0, 6000.0],
                    rtol=1e-3)


def test_phase_codes_are_the_simulators() -> None:
    from fetch_env.controller import PHASES as SIM_PHASES

    assert tuple(SIM_PHASES) == PHASES


def test_loader_imports_no_simulator() -> None:
    code = ("import sys, estimators.trace_files; "
            "bad = [m for m in sys.modules if m.split('.')[0] in ('mujoco', 'fetch_env', "
            "'agents')]; assert not bad, bad")
    subprocess.run([sys.executable, "-c", code], check=True)


# ----------------------------------------------------------------------------- bad files

def _good_csv() -> dict[str, np.ndarray]:
    return synthetic_relaxation(n=30)


def _csv_text(columns: dict[str, Any], meta: str = "# L: 0.04\n# theta_0: 0\n") -> str:
    rows = zip(*(np.asarray(v) for v in columns.values()), strict=True)
    body = "\n".join(",".join(repr(float(x)) for x in r) for r in rows)
    return meta + ",".join(columns) + "\n" + body


def _set_cell(text: str, line: int, column: int, value: str) -> str:
    """``text`` with the cell at (1-based ``line``, 0-based ``column``) replaced by ``value``."""
    lines = text.splitlines()
    cells = lines[line - 1].split(",")
    cells[column] = value
    lines[line - 1] = ",".join(cells)
    return "\n".join(lines)


def _bad_files() -> dict[str, tuple[str, str | bytes, str]]:
    """name -> (file name, contents, fragment the error must contain)."""
    good = _good_csv()
    text = _csv_text(good)  # lines 1-2 metadata, 3 the header t,theta,moment_left,moment_right
    return {
        "binary": ("x.csv", b"\x89PNG\r\n\x1a\n\x00\xff\xfe", "not a text file"),
        "empty": ("x.csv", "\n  \n", "empty file"),
        "prose": ("x.txt", "hello, this is not\njust words\n", "missing column 't'"),
        "one-column": ("x.txt", "just some words\nand more\n", "not a CSV file"),
        "bad-json": ("x.json", '{"traces": [1, 2', "not valid JSON"),
        "json-no-traces": ("x.json", '{"t": [1, 2]}', "JSON without a 'traces' object"),
        "json-fetch": ("x.json", json.dumps({"experiment": "fetch", "traces": {}}),
                       "experiment 'fetch' has no probe data"),
        "json-string": ("x.json", json.dumps({"traces": {"t": ["a"]}}),
                        "traces.t[0]: 'a' is not a number"),
        "no-time": ("x.csv", _csv_text({k: v for k, v in good.items() if k != "t"}),
                    "missing column 't'"),
        "no-theta": ("x.csv", _csv_text({k: v for k, v in good.items() if k != "theta"}),
                     "missing column 'theta': the relaxation probe needs theta, moment_left, "
                     "moment_right together"),
        "half-spoon": ("x.csv", _csv_text({k: v for k, v in good.items()
                                           if k != "moment_right"}),
                       "one half-spoon missing: column 'moment_left' without 'moment_right'"),
        "half-force": ("x.csv", _csv_text({"t": good["t"], "normal_left": good["t"],
                                           "tangential_left": good["t"],
                                           "tangential_right": good["t"]}),
                       "column 'normal_left' without 'normal_right'"),
        "no-probe": ("x.csv", _csv_text({"t": good["t"], "lift": good["t"]}),
                     "no slip data (normal_left, normal_right, tangential_left, tangential_right)"
                     "; columns found: t, lift"),
        "non-numeric": ("x.csv", _set_cell(text, 6, 1, "abc"),
                        "line 6, column 'theta': 'abc' is not a number"),
        "empty-cell": ("x.csv", _set_cell(text, 7, 2, " "),
                       "line 7, column 'moment_left': empty cell is not a number"),
        "nan": ("x.csv", _set_cell(text, 9, 3, "nan"),
                "column 'moment_right' has nan at line 9"),
        "inf": ("x.csv", _set_cell(text, 10, 1, "-inf"), "column 'theta' has -inf at line 10"),
        "time-back": ("x.csv", _set_cell(text, 12, 0, "0.0"),
                      "time not strictly increasing at line 12"),
        "too-short": ("x.csv", "\n".join(text.splitlines()[:3 + 12]),
                      f"too short: 12 samples, at least {MIN_SAMPLES} are needed"),
        "ragged": ("x.csv", _set_cell(text, 5, 0, "0.1,1"),
                   "line 5 has 5 cells, the header has 4"),
        "no-geometry": ("x.csv", _csv_text(good, meta=""),
                        "clamp geometry missing: lever arm L [m]: --L"),
        "no-theta-0": ("x.csv", _csv_text(good, meta="# L: 0.04\n"),
                       "clamp geometry missing: theta_0 [rad]: --theta-0"),
        "bad-metadata": ("x.csv", _csv_text(good, meta="# L: 4 cm\n# theta_0: 0\n"),
                         "L (line 1): '4 cm' is not a number"),
        "negative-L": ("x.csv", _csv_text(good, meta="# L: -0.04\n# theta_0: 0\n"),
                       "clamp geometry: lever arm L must be in (0, 1] m, got -0.04"),
        "L-in-mm": ("x.csv", _csv_text(good, meta="# L: 40\n# theta_0: 0\n"),
                    "clamp geometry: lever arm L must be in (0, 1] m, got 40.0"),
        "theta-0-in-degrees": ("x.csv", _csv_text(good, meta="# L: 0.04\n# theta_0: 5\n"),
                               "theta_0 must be within (-pi/2, pi/2) rad, got 5.0"),
        "time-in-ns": ("x.csv", _csv_text({**good, "t": good["t"] * 1e-9}),
                       "below 1e-06 s (a megahertz): t must be in seconds"),
        "sample-too-large": ("x.csv", _set_cell(text, 8, 2, "1e300"),
                             "beyond +-1e+12"),
        "json-huge-integer": ("x.json", '{"traces": {"t": [' + "9" * 400 + "]}}",
                              "traces.t[0]: 99999999999999999999... is beyond a float's range"),
        "json-too-many-digits": ("x.json", '{"traces": {"t": [' + "9" * 5000 + "]}}",
                                 "not readable JSON: Exceeds the limit (4300 digits)"),
        "json-nested": ("x.json", '{"traces": ' + "[" * 100000 + "]" * 100000 + "}",
                        "not readable JSON: nested too deeply"),
        "late-clamp": ("x.csv", _csv_text(good, meta="# L: 0.04\n# theta_0: 0\n"
                                          "# clamp_start: 99\n"),
                       "clamp_start = 99.0 s is outside the recorded time"),
    }


BAD = _bad_files()


@pytest.mark.parametrize("kind", list(BAD))
def test_bad_file_is_one_line_exit_2(
    kind: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    name, contents, fragment = BAD[kind]
    path = tmp_path / name
    if isinstance(contents, bytes):
        path.write_bytes(contents)
    else:
        path.write_text(contents)
    code, out, err = run_cli(["estimate", "--traces", str(path)], capsys)
    assert_one_line_error(code, err)
    assert str(path) in err and fragment in err, err
    assert out == ""
    with pytest.raises(TraceFileError) as info:  # the Python API: the typed error
        load_traces(path)
    assert fragment in str(info.value) and info.value.path == str(path)
    assert isinstance(info.value, EstimationError) and isinstance(info.value, ValueError)


@pytest.mark.parametrize(("args", "fragment"), [
    (["--traces", "{missing}"], "cannot read: No such file or directory"),
    (["--traces", "{dir}"], "cannot read"),
    (["--traces", "{good}", "--probe", "slip"], "no slip data (the file has relaxation data)"),
    (["--traces", "{good}", "--young", "2e5"], "--young cannot be used with --traces"),
    (["--traces", "{good}", "--noise", "0", "--shape", "cube"],
     "--noise, --shape cannot be used with --traces"),
    (["--traces", "{good}", "--clamp-weight", "1"], "--clamp-weight cannot be used"),
    (["--traces", "{good}", "--hold", "3"], "--hold cannot be used"),
    (["--traces", "{good}", "--L", "abc"], "--L: not a number"),
    (["--L", "0.04"], "--L needs --traces FILE"),
    (["--traces", "{good}", "--json", "{good}"], "--traces and --json name the same file"),
    (["--theta-0", "0", "--L", "0.04"], "--L and --theta-0 need --traces FILE"),
    (["--contact-angle", "0.005"], "--contact-angle needs --traces FILE"),
    (["--traces", "{good}", "--contact-angle", "0.005", "--method", "three-step"],
     "--contact-angle is for the full fit"),
    (["--traces", "{good}", "--contact-angle", "0.03"],
     "--contact-angle 0.03 rad must be in [0, 0.024) rad"),
    (["--traces", "{good}", "--contact-angle", "-0.001"], "--contact-angle -0.001 rad must be"),
    (["--mu-reading", "study"], "--mu-reading needs --traces FILE"),
    (["--traces", "{good}", "--mu-reading", "study"],
     "--mu-reading is for a slip trace, and none is estimated here"),
    (["--traces", "{good}", "--mu-reading", "plateau"], "invalid choice: 'plateau'"),
], ids=lambda v: v if isinstance(v, str) else " ".join(v))
def test_bad_option_is_one_line_exit_2(
    args: list[str], fragment: str, tmp_path: Path, capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    from fetch_env.controller import FetchSimulator

    def refuse(*_a: object, **_k: object) -> None:
        raise AssertionError("simulated with --traces or --L")

    monkeypatch.setattr(FetchSimulator, "run", refuse)
    good = tmp_path / "good.csv"
    good.write_text(_csv_text(_good_csv()))
    paths = {"{missing}": str(tmp_path / "nope.csv"), "{dir}": str(tmp_path),
             "{good}": str(good)}
    code, _, err = run_cli(["estimate", *(paths.get(a, a) for a in args)], capsys)
    assert_one_line_error(code, err)
    assert fragment in err, err


def test_json_missing_geometry_uses_options(
    sim_docs: dict[str, Path], tmp_path: Path
) -> None:
    """Geometry from the options beats the file's; without either, the error names it."""
    doc = json.loads(sim_docs["relaxation"].read_text())
    theta_0 = doc.pop("geometry")["theta_0"]
    path = tmp_path / "nogeom.json"
    path.write_text(json.dumps(doc))
    with pytest.raises(TraceFileError, match=r"clamp geometry missing: lever arm L .*theta_0"):
        load_traces(path)
    traces = load_traces(path, L=0.05, theta_0=0.01)
    assert traces.geometry == ClampGeometry(L=0.05, theta_0=0.01)
    assert traces.source["L"] == "given" and traces.source["clamp_start"].startswith("extra.")
    traces = load_traces(sim_docs["relaxation"], L=0.05)
    assert traces.geometry == ClampGeometry(L=0.05, theta_0=theta_0)
