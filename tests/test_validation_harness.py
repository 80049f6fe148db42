"""The estimator validation harness and its committed reporting-set results.

The default run re-measures a handful of reporting foods (the first four of the design,
not picked by result) and holds them to the committed records, and checks what the
committed summary claims; the full 64-food runs are ``benchmarks/validate_estimators.py``.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from numpy.testing import assert_allclose
from scipy.stats import beta

from benchmarks.reproducibility import OTHER_KERNELS_RTOL, kernels_match_committed
from benchmarks.validate_estimators import (
    _speed_line,
    calibrate,
    coverage_interval,
    coverage_text,
    food_seed,
    foods_of,
    measure,
    summarize,
)
from fetch_env.probes import PARAM_NAMES

DATA = Path(__file__).resolve().parents[1] / "docs" / "data" / "validation"
REPORTS = {preset: json.loads((DATA / f"reporting_{preset}_noise0.json").read_text())
           for preset in ("precise", "repeated", "measure")}


@pytest.mark.parametrize(("preset", "index"), [("precise", 0), ("repeated", 0), ("repeated", 1),
                                               ("measure", 0), ("measure", 1), ("measure", 2),
                                               ("measure", 3)])
def test_reporting_foods_measure_as_committed(preset: str, index: int) -> None:
    """Same food, same probes: the same estimates and intervals as the committed run (the
    harness is deterministic: to 1e-6 where numpy's kernels are the committed run's, to
    ``OTHER_KERNELS_RTOL`` of the estimate elsewhere), every estimate found, and the truth
    inside the g1 and mu intervals wherever the committed run had it there."""
    food = foods_of("reporting", 64)[index]
    rec = measure(food, preset, 0.0, food_seed(food))
    old = next(r for r in REPORTS[preset]["records"] if r["food"]["index"] == index)
    same = kernels_match_committed()
    for k in PARAM_NAMES:
        assert_allclose(rec["estimate"][k], old["estimate"][k],
                        rtol=1e-6 if same else OTHER_KERNELS_RTOL, err_msg=k)
        if same:
            assert_allclose(rec["interval"][k], old["interval"][k], rtol=1e-6, err_msg=k)
        elif np.ptp(old["interval"][k]) < abs(old["estimate"][k]):
            # where kernels differ, a bound to that share of the estimate (measured: 1.1 %);
            # an interval wider than its estimate (K2 of `measure` food 1: 8.6 times) says the
            # parameter is not identified, and its bounds move by a fifth of the width
            assert_allclose(rec["interval"][k], old["interval"][k], rtol=0.0,
                            atol=OTHER_KERNELS_RTOL * abs(old["estimate"][k]), err_msg=k)
    assert rec["covered"]["g1"] and rec["covered"]["mu"]
    # within the reporting runs' largest misses (g1 17.3 % with `measure`, mu 12.2 %)
    assert abs(rec["error"]["g1"]) < 0.174 and abs(rec["error"]["mu"]) < 0.123


@pytest.mark.parametrize("preset", ["precise", "repeated", "measure"])
def test_committed_summary_holds_what_the_docs_say(preset: str) -> None:
    """Recomputed from the records: the 95 % intervals of g1, tau1 and mu cover the truth on
    at least 90 % of the 64 reporting foods, and no food with a g1, tau1 or mu error over 5 %
    is flagged reliable."""
    report = REPORTS[preset]
    s = summarize(report["records"])
    for k in PARAM_NAMES:
        for field in ("median", "p95", "max", "coverage"):
            assert_allclose(s[k][field], report["summary"][k][field], rtol=1e-12)
    assert s["reliability"] == report["summary"]["reliability"]
    assert s["n_foods"] == 64 and s["n_crashed"] == 0
    for k in ("g1", "tau1", "mu"):
        assert 0.90 <= s[k]["coverage"] <= 1.0, (k, s[k]["coverage"])
    assert s["reliability"]["over_5pct_flagged_reliable"] == 0


@pytest.mark.parametrize("noise", ["0", "0.01"])
def test_the_precise_reporting_runs_flag_as_the_bar_asks(noise: str) -> None:
    """The committed precise reporting runs, without and with 1 % noise: on the 64 foods no
    food with a g1, tau1 or mu error over 5 % is called reliable; on the 256 (the 64 and
    192 more) at most 10 % of those with every error under 2 % are called unreliable
    (measured: 14 of 225 and 17 of 204)."""
    records = json.loads((DATA / f"reporting_precise_noise{noise}.json").read_text())["records"]
    rel = summarize(records)["reliability"]
    assert rel["over_5pct_flagged_reliable"] == 0, rel
    larger = json.loads((DATA / f"reporting256_precise_noise{noise}.json").read_text())
    rel = summarize(larger["records"])["reliability"]
    assert rel["n_under_2pct"] >= 180, rel
    assert rel["under_2pct_flagged_unreliable"] <= 0.10 * rel["n_under_2pct"], rel


@pytest.mark.xfail(strict=True, reason="one food past the bar: 6 of 57 (10.5 %) without noise, "
                   "5 of 49 (10.2 %) with 1 % noise; docs/estimator_validation.md")
@pytest.mark.parametrize("noise", ["0", "0.01"])
def test_the_64_reporting_foods_call_at_most_a_tenth_of_the_good_ones_unreliable(
        noise: str) -> None:
    """The bar on the 64 reporting foods themselves: at most 10 % of the foods with every
    error under 2 % called unreliable.  Known short by one food (the reason above); strict,
    so that a change that meets it fails here until the mark is taken off."""
    records = json.loads((DATA / f"reporting_precise_noise{noise}.json").read_text())["records"]
    rel = summarize(records)["reliability"]
    assert rel["n_under_2pct"] >= 40, rel
    assert rel["under_2pct_flagged_unreliable"] <= 0.10 * rel["n_under_2pct"], rel


def test_speed_summary_counts_the_foods_past_the_bars() -> None:
    """The speed line counts the foods past the 10 s and 50 ms bars among those timed: a
    crashed food and one without a CPU time are left out of both the count and its total."""
    def food(probes: float, fits: float) -> dict[str, object]:
        return {"error": dict.fromkeys(PARAM_NAMES, 0.001),
                "covered": dict.fromkeys(PARAM_NAMES, True), "reliable": True,
                "wall_probes": probes, "wall_fits": fits, "cpu_probes": probes,
                "cpu_fits": fits}

    records = [food(5.0, 0.02), food(12.0, 0.06), food(9.0, 0.03), food(11.0, 0.01),
               food(math.nan, math.nan), {"crash": "diverged"}]
    s = summarize(records)
    assert (s["cpu_probes_over_bar"], s["cpu_probes_n"]) == (2, 4)
    assert (s["cpu_fits_over_bar"], s["cpu_fits_n"]) == (1, 4)
    line = _speed_line(s)
    assert "max 12.00 s, 2 of 4 over 10 s" in line
    assert "median 25.0 ms" in line and "1 of 4 over 50 ms" in line
    committed = summarize(REPORTS["precise"]["records"])
    assert committed["cpu_fits_median"] < 0.05  # the fits' bar, on the reporting foods


def test_calibrate_returns_the_quantile_of_the_missing_sd() -> None:
    """Foods whose own intervals have sd 0.01 and that miss by 1.96 * (0.01 ... 0.20)
    need a systematic sd of sqrt(x^2 - 0.01^2); 95 % coverage takes its 95th percentile."""
    z = 1.959963984540054
    misses = [0.01 * (i + 1) for i in range(20)]
    recs = [{"error": dict.fromkeys(PARAM_NAMES, math.expm1(z * m)),
             "interval": dict.fromkeys(PARAM_NAMES, (math.exp(-z * 0.01), math.exp(z * 0.01)))}
            for m in misses]
    for r in recs:
        r["interval"] = {k: (v[0] * (1 + r["error"][k]), v[1] * (1 + r["error"][k]))
                         for k, v in r["interval"].items()}
        r["error"] = dict(r["error"])
    out = calibrate(recs, dict.fromkeys(PARAM_NAMES, 0.0))
    need = sorted(math.sqrt(max(m**2 - 0.01**2, 0.0)) for m in misses)
    assert_allclose(out["g1"], np.quantile(need, 0.95), rtol=1e-9)


def test_readme_estimator_table_is_the_committed_json() -> None:
    """The README's estimator table is what scripts/make_validation_page.py makes from the
    committed reporting runs (regenerate it after a new run, never edit it by hand)."""
    import importlib.util

    path = Path(__file__).resolve().parents[1] / "scripts" / "make_validation_page.py"
    spec = importlib.util.spec_from_file_location("make_validation_page", path)
    assert spec is not None and spec.loader is not None
    page = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(page)
    readme = page.README.read_text()
    block = readme[readme.index(page.MARK_BEGIN) + len(page.MARK_BEGIN):
                   readme.index(page.MARK_END)]
    assert block.strip() == page.readme_table().strip()


def test_default_probes_meet_the_reporting_sets_figures_on_its_first_foods() -> None:
    """A reduced accuracy check over the food space in the default run: ``food-fetch
    estimate``'s probes (``precise``) on the first 8 reporting foods (3 cubes, 3 spheres,
    2 ellipsoids, 0.02-4.8 MPa), recomputed: each g1 and tau1 within the issue's 3 % (the
    reporting set's 95th percentiles: 1.96 and 2.14 %), their medians within the issue's
    1 % (the set's: 0.32 and 0.37 %), mu's median within 1 %, the medians of K1, K2 and B
    within 3 % (the set's: 1.45, 1.38 and 1.66 %), and the g1 and tau1 intervals covering
    the truth on at least 7 of the 8 (committed: g1 at most 0.67 %, tau1 0.86 %, all 8
    covered; K1, K2, B medians 1.3, 1.1, 1.5 %)."""
    recs = [measure(food, "precise", 0.0, food_seed(food))
            for food in foods_of("reporting", 64)[:8]]
    names = ("g1", "tau1", "mu", "K1", "K2", "B")
    err = {k: np.array([abs(r["error"][k]) for r in recs]) for k in names}
    assert err["g1"].max() <= 0.03 and err["tau1"].max() <= 0.03, err
    assert np.median(err["g1"]) <= 0.01 and np.median(err["tau1"]) <= 0.01, err
    assert np.median(err["mu"]) <= 0.01, err["mu"]
    for k in ("K1", "K2", "B"):
        assert np.median(err[k]) <= 0.03, (k, err[k])
    for k in ("g1", "tau1"):
        assert sum(bool(r["covered"][k]) for r in recs) >= 7, k


def test_coverage_interval_is_the_exact_binomial_one() -> None:
    """k of n: Clopper-Pearson's bounds, the Beta quantiles (n of n: alpha/2 ** (1/n) to 1;
    0 of n: 0 to 1 - alpha/2 ** (1/n)), and the table's text of them."""
    assert_allclose(coverage_interval(1.0, 64), (0.025 ** (1 / 64), 1.0), rtol=1e-9)
    assert_allclose(coverage_interval(0.0, 64), (0.0, 1 - 0.025 ** (1 / 64)), rtol=1e-9)
    lo, hi = coverage_interval(61 / 64, 64)
    assert_allclose((lo, hi), (beta.ppf(0.025, 61, 4), beta.ppf(0.975, 62, 3)), rtol=1e-7)
    assert coverage_text(1.0, 64) == "100 % of 64 (94.4-100 %)"
    assert coverage_text(61 / 64, 64) == f"95 % of 64 ({100 * lo:.1f}-{100 * hi:.1f} %)"
    assert coverage_text(62 / 64, 64) == "97 % of 64 (89.2-99.6 %)"
    assert coverage_text(math.nan, 0) == "-"


def test_kept_simulations_give_the_records_of_a_run_that_simulates(tmp_path: Path) -> None:
    """``--simulations``: the first run keeps each food's simulations and truth, a later run
    with other noise or calibration fits them again; both give the records a run without
    them gives (estimates, intervals and truth equal), and a kept file made for other probe
    settings is refused in the record, not fitted."""
    food = foods_of("reporting", 64)[0]
    kept = str(tmp_path / "sims")
    for noise, calibrated in ((0.0, True), (0.01, False)):
        plain = measure(food, "measure", noise, food_seed(food), calibrated)
        stored = measure(food, "measure", noise, food_seed(food), calibrated, simulations=kept)
        for key in ("estimate", "interval", "truth", "warnings", "reliable"):
            assert stored[key] == plain[key], key
        assert stored["cpu_probes"] > stored["cpu_fits"] > 0.0
    assert [p.name for p in (tmp_path / "sims").iterdir()] == ["food0.pickle"]
    other = measure(food, "env", 0.0, food_seed(food), simulations=kept)
    assert "runs were simulated for another config" in other["crash"]


NOISE_DRAWS = (0, 1, 2, 3)


def _draw(stem: str, k: int) -> dict[str, object]:
    name = stem if k == 0 else f"{stem}_draw{k}"
    return json.loads((DATA / f"{name}.json").read_text())


def test_noise_draws_have_seeds_of_their_own() -> None:
    """Every (food, draw) pair of the largest design has its own noise seed, and draw 0 is
    the seed every committed run with noise used."""
    foods = foods_of("tuning", 512)
    seeds = {food_seed(f, k) for f in foods for k in range(4)}
    assert len(seeds) == 4 * 512
    assert [food_seed(f) for f in foods[:3]] == [1, 7920, 15839]


@pytest.mark.parametrize("k", NOISE_DRAWS[1:])
def test_the_committed_noise_draws_are_the_same_foods_with_other_noise(k: int) -> None:
    """Each extra draw: the reporting run's foods and settings, its summary recomputed from
    its records, and noise that differs from draw 0's (a food's mu reading moves)."""
    base, other = _draw("reporting_precise_noise0.01", 0), _draw("reporting_precise_noise0.01", k)
    assert other["meta"]["noise_draw"] == k and other["meta"]["noise"] == 0.01
    assert [r["food"] for r in other["records"]] == [r["food"] for r in base["records"]]
    assert summarize(other["records"])["reliability"] == other["summary"]["reliability"]
    moved = [abs(a["estimate"]["mu"] / b["estimate"]["mu"] - 1)
             for a, b in zip(other["records"], base["records"], strict=True)]
    assert np.median(moved) > 1e-4


def test_over_four_noise_draws_the_reporting_foods_call_no_miss_reliable() -> None:
    """The reporting foods with 1 % noise, four independent draws (docs/estimator_validation
    .md, "The flag over four noise draws"): no food more than 5 % off in g1, tau1 or mu
    called reliable in any draw (0 of 15), and 24 of 196 good ones (12.2 %) flagged."""
    rel = [summarize(_draw("reporting_precise_noise0.01", k)["records"])["reliability"]
           for k in NOISE_DRAWS]
    assert sum(r["over_5pct_flagged_reliable"] for r in rel) == 0
    assert sum(r["n_over_5pct"] for r in rel) == 15
    flagged = sum(r["under_2pct_flagged_unreliable"] for r in rel)
    good = sum(r["n_under_2pct"] for r in rel)
    assert (flagged, good) == (24, 196)


def test_the_page_shows_the_noise_draws_as_the_committed_runs_give_them() -> None:
    """docs/estimator_validation.md's section on the noise draws is what the committed runs
    give now, the tuning foods' held-out flags included (each fold's calibration refitted,
    benchmarks.validate_estimators.cross_validate with ``evaluate``)."""
    import importlib.util
    path = Path(__file__).resolve().parents[1] / "scripts" / "make_validation_page.py"
    spec = importlib.util.spec_from_file_location("make_validation_page", path)
    assert spec is not None and spec.loader is not None
    page_module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(page_module)
    section = page_module.noise_draws_section()
    assert section and "| 512 tuning, held out | all | 7 of 105 / 169 of 1589 (10.6 %)" in section
    page = (path.parents[1] / "docs" / "estimator_validation.md").read_text()
    assert section in page


@pytest.mark.parametrize("argv", [
    ["--noise-draw", "1"], ["--noise", "0.01", "--noise-draw", "-1"],
    ["--noise", "0.01", "--noise-draw", "1001"],
    ["--noise-draw", "2", "--fit-calibration", "run.json"],
    ["--noise-draw", "2", "--calibrate", "run.json"]])
def test_a_noise_draw_it_cannot_use_is_refused(
        argv: list[str], tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """--noise-draw goes with --noise > 0, lies in [0, 1000] and makes a run (not with
    --fit-calibration or --calibrate): refused in one line with exit 2 before any work."""
    from benchmarks import validate_estimators
    with pytest.raises(SystemExit) as exc:
        validate_estimators.main([*argv, "--n", "1", "--out", str(tmp_path)])
    assert exc.value.code == 2
    assert "--noise-draw" in capsys.readouterr().err.strip().splitlines()[-1]
    assert not list(tmp_path.iterdir())


def test_the_noise_draw_reaches_each_foods_noise_seed(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    """The tasks a run with --noise-draw 3 hands its pool carry each food's draw-3 seed, and
    its files are named _draw3."""
    from benchmarks import validate_estimators as ve
    seen: list[tuple[object, ...]] = []

    def pool(fn: object, tasks: list[tuple[object, ...]], *rest: object) -> str:
        seen.extend(tasks)
        return "interrupted (SIGTERM)"

    monkeypatch.setattr(ve, "run_streamed", pool)
    code = ve.main(["--set", "reporting", "--n", "3", "--noise", "0.01", "--noise-draw", "3",
                    "--out", str(tmp_path)])
    assert code == 143
    foods = foods_of("reporting", 3)
    assert [t[3] for t in seen] == [food_seed(f, 3) for f in foods]
    assert str(tmp_path / "reporting_precise_noise0.01_draw3.jsonl") in capsys.readouterr().err


def test_a_resumed_stream_drops_a_line_cut_short(tmp_path: Path) -> None:
    from benchmarks.validate_estimators import drop_cut_line
    jsonl = tmp_path / "run.jsonl"
    jsonl.write_text('{"food": {"index": 0}}\n{"food": {"ind')
    drop_cut_line(jsonl)
    assert jsonl.read_text() == '{"food": {"index": 0}}\n'
    drop_cut_line(jsonl)  # a complete file is left as it is
    assert jsonl.read_text() == '{"food": {"index": 0}}\n'
