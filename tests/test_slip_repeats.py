"""Repeated slides of the slip probe (``ProbeConfig.slip_repeats``): their durations, how
their estimates of mu are combined, the spread the error model reads, and the accuracy the
median buys on simulated foods of the whole space."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from numpy.testing import assert_allclose

from estimators.calibration import (
    ERROR_INPUTS,
    OPTIONAL_ERROR_INPUTS,
    Calibration,
    ErrorModel,
    fit_error_model,
)
from estimators.errors import EstimationError
from estimators.uncertainty import Z95
from fetch_env.errors import InvalidParameterError
from fetch_env.food_space import sample_foods
from fetch_env.probes import (
    PARAM_NAMES,
    PROBE_PRESETS,
    ProbeConfig,
    ProbeOutcome,
    estimate_mu,
    slide_times,
    slip_run,
)
from fetch_env.probes.slip import _median_of_slides, _SlideFit, _slip_probe
from tests.test_error_model import _synthetic_rows

CHECK_SEED = 3000  # the estimator check foods (tuning 1000, reporting 2000)


def test_slides_alternate_slower_and_faster() -> None:
    config = ProbeConfig(slide_time=0.3, slip_repeats=5)
    assert_allclose(slide_times(config), [0.3, 0.45, 0.2, 0.675, 0.3 / 2.25], rtol=1e-12)
    assert slide_times(ProbeConfig()) == [ProbeConfig().slide_time]
    assert slide_times(PROBE_PRESETS["precise"])[0] == PROBE_PRESETS["precise"].slide_time


@pytest.mark.parametrize("value", [0, 10, True, 2.0, "3"])
def test_bad_slip_repeats_name_the_value(value: object) -> None:
    with pytest.raises(InvalidParameterError, match="slip_repeats"):
        ProbeConfig(slip_repeats=value)  # type: ignore[arg-type]


def _slide(mu: float, half_width: float = 0.02, gap: float = 0.01) -> _SlideFit:
    return _SlideFit(mu, [f"slide {mu}"], (mu * math.exp(-half_width), mu * math.exp(half_width)),
                     {"mu_gap": gap, "mu_plateau": 1.0})


def test_the_median_slide_sets_mu_and_the_spread_widens_its_interval() -> None:
    fits = [_slide(0.40, gap=0.01), _slide(0.44, gap=0.03), _slide(0.39, gap=0.05)]
    out = _median_of_slides(fits, 3)
    assert out.mu == 0.40 and out.warnings == ["slide 0.4"]
    assert_allclose(out.diagnostics["mu_trials"], 0.5 * math.log(0.44 / 0.39), rtol=1e-12)
    assert_allclose(out.diagnostics["mu_gap"], 0.03, rtol=1e-12)
    spread = np.std(np.log([0.40, 0.44, 0.39]), ddof=1)
    expected = math.hypot(0.02 / Z95, spread) * Z95
    assert_allclose(math.log(out.interval[1] / out.mu), expected, rtol=1e-9)
    assert_allclose(math.log(out.mu / out.interval[0]), expected, rtol=1e-9)


def test_one_slide_is_its_own_estimate_with_no_spread() -> None:
    fit = _slide(0.3)
    out = _median_of_slides([fit], 1)
    assert (out.mu, out.interval, out.warnings) == (fit.mu, fit.interval, fit.warnings)
    assert out.diagnostics["mu_trials"] == 0.0


@pytest.mark.filterwarnings("ignore::fetch_env.errors.ParameterClippedWarning")
def test_the_probe_reads_the_median_of_its_slides() -> None:
    """On a simulated food the repeated probe's mu is the median of the three slides'
    estimates, each from its own slip run, and its first slide's action is kept."""
    food = sample_foods(3, CHECK_SEED)[2]
    config = dataclasses.replace(PROBE_PRESETS["precise"], slip_repeats=3)
    out = ProbeOutcome(estimates=dict.fromkeys(PARAM_NAMES, math.nan), visco_valid=False,
                       friction_valid=False, wall_time=0.0, piece_index=0)
    _slip_probe(food.piece(), config, None, 0.0, np.random.default_rng(0), out, False)
    own = [estimate_mu(slip_run(food.piece(), dataclasses.replace(config, slide_time=t)),
                       envelope=config.slip_envelope)[0] for t in slide_times(config)]
    assert out.friction_valid and out.estimates["mu"] == np.median(own)
    assert_allclose(out.details["diagnostics"]["mu_trials"],
                    0.5 * math.log(max(own) / min(own)), rtol=1e-12)
    assert out.details["slip_action"]["slide_time"] == config.slide_time


@pytest.mark.filterwarnings("ignore::fetch_env.errors.ParameterClippedWarning")
def test_the_median_of_five_slides_misses_on_fewer_foods() -> None:
    """On 64 foods of the whole space (seed 3000, never tuned on), the precise probe's median
    of five slides (0.3, 0.45, 0.2, 0.675 and 0.133 s) misses mu by more than 1.4 % on at
    most 3 foods, fewer than its first slide alone and no more than the median of the first
    three, with a 95th percentile of at most 1.3 %; where the five slides agree within 0.1 %
    (half the log-range), none misses by more than 1 %.  Measured: 2 foods against 6 (3 for
    three slides), 95th percentile 1.11 % against 1.91 % (1.25 %), worst 2.5 %; the 25 foods
    whose slides agree within 0.1 % are all within 0.43 %."""
    config = PROBE_PRESETS["precise"]
    assert config.slip_repeats == 5
    errors, three, single, spread = [], [], [], []
    for food in sample_foods(64, CHECK_SEED):
        mus = [estimate_mu(slip_run(food.piece(), dataclasses.replace(config, slide_time=t)),
                           envelope=config.slip_envelope)[0] for t in slide_times(config)]
        errors.append(abs(np.median(mus) / food.mu - 1))
        three.append(abs(np.median(mus[:3]) / food.mu - 1))
        single.append(abs(mus[0] / food.mu - 1))
        spread.append(0.5 * math.log(max(mus) / min(mus)))
    errors_a, single_a, spread_a = np.array(errors), np.array(single), np.array(spread)
    assert np.sum(errors_a > 0.014) <= 3
    assert np.sum(errors_a > 0.014) < np.sum(single_a > 0.014)
    assert np.sum(errors_a > 0.014) <= np.sum(np.array(three) > 0.014)
    assert np.percentile(errors_a, 95) <= 0.013
    assert np.all(errors_a[spread_a < 0.001] <= 0.01)


def _rows_with_trials(n: int, seed: int) -> list[tuple]:
    """Synthetic foods whose mu error is set by the slides' spread (``mu_trials``) alone."""
    rng = np.random.default_rng(seed)
    rows = []
    for shape, size, est, diag, resid in _synthetic_rows(n, seed):
        trials = float(math.exp(rng.uniform(-7, -2.5)))
        diag = dict(diag, mu_trials=trials)
        resid = dict(resid, mu=float(rng.laplace(0.0, 1.5 * trials)))
        rows.append((shape, size, est, diag, resid))
    return rows


def test_the_error_model_reads_the_slides_spread_where_every_food_has_it() -> None:
    """Fitted on foods whose mu error follows the slides' spread, the mu model takes it as an
    input (:data:`OPTIONAL_ERROR_INPUTS`), covers 92-99 % of new foods and gives the half of
    them with the smaller spread narrower intervals than a model without it; it round-trips
    through the calibration file's form.  Foods without the spread keep the base inputs."""
    train, test = _rows_with_trials(400, 11), _rows_with_trials(2000, 12)
    model = fit_error_model(train)
    assert model.input_names("mu") == ERROR_INPUTS["mu"] + OPTIONAL_ERROR_INPUTS["mu"]
    assert model.input_names("g1") == ERROR_INPUTS["g1"]
    hw = np.array([model.half_width("mu", *row[:4]) for row in test])
    err = np.array([abs(row[4]["mu"]) for row in test])
    assert 0.92 <= np.mean(err <= hw) <= 0.99
    without = fit_error_model([(*row[:3], {k: v for k, v in row[3].items() if k != "mu_trials"},
                                row[4]) for row in train])
    assert without.input_names("mu") == ERROR_INPUTS["mu"]
    hw_without = np.array([without.half_width("mu", *row[:4]) for row in test])
    calm = np.array([row[3]["mu_trials"] for row in test]) < np.median(
        [row[3]["mu_trials"] for row in test])
    assert np.median(hw[calm]) < 0.5 * np.median(hw_without[calm])
    cal = Calibration({t: [0.0] * 8 for t in ("K_el", "g1", "tau1")}, error_model=model)
    assert Calibration.from_dict(cal.to_dict()).error_model == model


def test_an_error_model_with_unknown_inputs_is_refused_by_name() -> None:
    data = fit_error_model(_rows_with_trials(200, 13)).to_dict()
    data["inputs"]["mu"] = [*data["inputs"]["mu"], "log_mu_made_up"]  # type: ignore[index]
    with pytest.raises(EstimationError, match="log_mu_made_up"):
        ErrorModel.from_dict(data)
    with pytest.raises(EstimationError, match="inputs"):
        ErrorModel({}, {}, {}, {}, inputs={"mu": ("cube",)})
