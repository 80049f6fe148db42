"""Slow environment checks: model-estimated observations against the oracle on held-back
seeds, and the check_env of the multi-row ids lives in test_env.py (marked slow).

Run: python -m pytest -q -m slow tests/test_env_slow.py
"""

from __future__ import annotations

import functools

import numpy as np
import pytest

from fetch_env.env import FoodFetchEnv

# Seeds never used by the fast tests, the benchmarks (those use < 3000) or any tuning (the
# probe settings were compared on 5000+).  64 scenes, not 16: the statistics below are
# tails of a wide distribution, and a 16-scene 75th percentile of tau1's error scatters by
# +-8 points (bootstrap over the 64 scenes' errors; +-4 points with 64), as wide as the gap
# between a good and a bad estimator.
HELD_BACK = range(90_000, 90_064)


@functools.lru_cache(maxsize=4)
def agreement(layout: str = "block", seeds=HELD_BACK, **kwargs) -> dict[str, np.ndarray]:
    """Relative error model/oracle - 1 per parameter over ``seeds`` (NaN where the model
    gave no estimate).  Cached: the tests below share one pass over the held-back scenes
    (~30 s); callers must not modify the arrays."""
    env = FoodFetchEnv(layout=layout, estimator="model", **kwargs)
    errs: dict[str, list[float]] = {k: [] for k in ("K1", "K2", "B", "mu", "g1", "tau1")}
    for seed in seeds:
        _, info = env.reset(seed=seed)
        for k in errs:
            est = info["estimated_params"][k]
            errs[k].append(np.nan if est is None else est / info["true_params"][k] - 1.0)
    return {k: np.array(v) for k, v in errs.items()}


def _summary(e: np.ndarray) -> tuple[float, float, float]:
    ok = np.isfinite(e)
    if not ok.any():
        return 0.0, np.nan, np.nan
    return float(ok.mean()), float(np.median(np.abs(e[ok]))), float(np.abs(e[ok]).max())


# Measured on HELD_BACK, uncalibrated (probe_calibrated=False), the default probes (the 6 s
# hold's scaled steps log-spaced, impratio 30 in the relaxation probe, the slip probe at a
# 10 ms step; chosen on seeds 5000-5191, measured here once after):
#   mu:   64 of 64; median 0.1 %, 75th percentile 1.3 %, 95th 6.7 %; 91 % within 4 %.
#   g1:   64 of 64; median 3.5 %, 75th percentile 5.8 %, 95th 10.8 %.
#   tau1: 64 of 64; median 3.5 %, 75th percentile 7.7 %, 95th 15.7 %.
#   K1, K2, B: std of log(model / oracle) 0.21 / 0.23 / 0.25.
# With a constant time scale instead (a 6 s relaxation hold time-scaled 8x, a 0.15 s slide
# sampled at 200 Hz):
#   mu:   64 of 64; median 0.2 %, 75th percentile 0.9 %, 95th 3.2 %; 95 % within 4 %.
#   g1:   64 of 64; median 2.5 %, 75th percentile 4.5 %, 95th 8.3 %.
#   tau1: 64 of 64; median 4.0 %, 75th percentile 9.7 %, 95th 28 %.
#   K1, K2, B: std of log(model / oracle) 0.21 / 0.23 / 0.25.
# Measured on HELD_BACK (64 sampled Block scenes), default probes (probe_hold 3 s), K1, K2, B,
# g1 and tau1 from the hold alone (probes.HOLD_SETTLE) and the relaxation probe's contact
# stiffened with the food (controller.relaxation_contact_timeconst); relative error
# |model / oracle - 1|:
#   mu:   identified 64 of 64; median 0.5 %, 75th percentile 1.4 %, 95th 9.5 % (max 18 %: a
#         soft piece that stick-slips); 88 % of scenes within 4 %.
#   g1:   identified 64 of 64; median 2.3 %, 75th percentile 4.0 %, 95th 12 %.
#   tau1: identified 64 of 64; median 6.0 %, 75th percentile 11.8 %, 95th 33 % (max 50 %).
#   K1, K2, B against the nominal stiffness: std of log(model / oracle) 0.22 / 0.24 / 0.29
#         (all from the hold; 0.52 / 0.52 / 0.55 with K1 from the full fit).
# With a 10 ms contact and tau1 from the full fit: g1 6.2 / 13.4 / 23 %, tau1 13.1 / 28.2 /
# 54 %, 63 of 64 identified; with the stiffened contact alone: g1 2.3 / 4.1 / 12 %, tau1 10.8 /
# 18.6 / 54 %.  With g1 from the full fit: g1 11.2 % / 21.6 %.  The bars: mu's as
# set on the first 16 scenes, its "max" read as the 95th percentile (the largest of 16
# samples estimates about that quantile, the largest of 64 about the 98th); g1's and tau1's
# set at the stiffened-contact figures with about 2x / 1.7x room, so that losing either change
# fails.  probe_hold=0.3 (the fast probes): mu as above; g1 / tau1 identified on < 50 %
# (docs/validation/probes.md).


def _p75(e: np.ndarray) -> float:
    return _percentile(e, 75)


def _percentile(e: np.ndarray, q: float) -> float:
    """The ``q``-th percentile of |e| over the scenes where it was identified."""
    return float(np.percentile(np.abs(e[np.isfinite(e)]), q))


@pytest.mark.slow
def test_default_probe_estimates_agree_with_the_oracle_on_held_back_seeds() -> None:
    errs = agreement()
    share, median, _ = _summary(errs["mu"])
    assert share >= 0.9, f"mu identified on {share:.0%} of seeds"
    p95 = _percentile(errs["mu"], 95)
    assert median < 0.01 and p95 < 0.15, f"mu: {errs['mu']}"
    share, median, _ = _summary(errs["g1"])
    assert share >= 0.9, f"g1 identified on {share:.0%} of seeds"
    assert median < 0.05 and _p75(errs["g1"]) < 0.1, f"g1: {errs['g1']}"
    share, _, _ = _summary(errs["tau1"])  # tau1's accuracy: its own tests below
    assert share >= 0.9, f"tau1 identified on {share:.0%} of seeds"
    # K1, K2, B are compared with a nominal stiffness (no contact mechanics, no Poisson
    # confinement): a common factor is allowed; the scatter about it is the shapes' contact.
    # Measured std of log(model/oracle): K1 0.28, K2 0.57, B 0.63 on the first 16 scenes
    # (g1 from the full fit), 0.53 / 0.57 / 0.46 on the 64 with a 10 ms contact, 0.22 / 0.24 / 0.29
    # with everything from the hold of a stiff-contact clamp; the bar is 0.4.
    for k in ("K1", "K2", "B"):
        ratio = 1.0 + errs[k][np.isfinite(errs[k])]
        assert np.std(np.log(ratio)) < 0.4, f"{k} ratios {ratio}"


@pytest.mark.slow
def test_mu_within_4_percent_on_most_held_back_seeds() -> None:
    errs = agreement()
    assert np.mean(np.abs(errs["mu"]) < 0.04) >= 0.85, f"mu: {errs['mu']}"


# tau1's bars: median 10 %, 75th percentile 20 % (the estimators issue's 13 % median, measured
# on simulated traces, with room to spare).  The hold is short of the slowest foods' tau1 (up
# to 6 s against a 3 s hold), and a stiff cube's held contact chatters, so tau1's errors stay
# wider than g1's.  From the full fit instead, tau1 was misled where the clamp does
# not rise as an SLS (round pieces rocking as the blades close), and MuJoCo's 10 ms contact
# was a spring in series with stiff pieces: the median sat at 13.1 % (a strict xfail on a
# 13 % bar) and the 75th percentile at 28 %.
@pytest.mark.slow
def test_tau1_median_within_10_percent() -> None:
    errs = agreement()
    assert _summary(errs["tau1"])[1] < 0.10, f"tau1: {errs['tau1']}"


@pytest.mark.slow
def test_tau1_75th_percentile_within_20_percent() -> None:
    errs = agreement()
    assert _p75(errs["tau1"]) < 0.2, f"tau1: {errs['tau1']}"


# The estimators issue's bar for the environments' observations on these 64 Block scenes:
# median at most 2 % and 95th percentile at most 10 % for g1, tau1 and mu.  The default 6 s
# probes miss it (tau1's 95th percentile 16 %).  The ``measure`` probes (a 20 s hold, a 0.3 s
# slide) with the food space's calibration gave g1 0.9 / 4.3 %, tau1 2.1 / 7.8 %, mu 0.1 /
# 1.8 % (median / 95th percentile); with the calibration fitted on 256 Block scenes of seed
# 95000 (fetch_env.probes.calibration_for, which the env applies), measured here once after
# it was fitted: g1 1.1 / 3.4 %, tau1 1.6 / 7.2 %, mu 0.1 / 1.8 %, for 1.37x the reset's CPU
# time (benchmarks/bench_env_estimates.py; docs/estimator_validation.md).
@pytest.mark.slow
@pytest.mark.parametrize("name", ["g1", "tau1", "mu"])
def test_measure_probes_meet_the_95th_percentile_bar_on_held_back_seeds(name: str) -> None:
    errs = agreement(probes="measure")[name]
    assert np.isfinite(errs).all(), f"{name} not identified on every scene: {errs}"
    assert _percentile(errs, 95) <= 0.10, f"{name}: {errs}"


@pytest.mark.slow
@pytest.mark.parametrize("name", ["g1", "tau1", "mu"])
def test_measure_probes_meet_the_median_bar_on_held_back_seeds(name: str) -> None:
    assert _summary(agreement(probes="measure")[name])[1] <= 0.02


if __name__ == "__main__":  # prints the figures quoted in the report
    import argparse

    parser = argparse.ArgumentParser(description="model / oracle - 1 on sampled Block scenes")
    parser.add_argument("probe_hold", type=float, nargs="?", default=None,
                        help="relaxation probe hold [s] (default: the env's)")
    parser.add_argument("--first-seed", type=int, default=HELD_BACK.start)
    parser.add_argument("--count", type=int, default=len(HELD_BACK))
    parser.add_argument("--contact-timeconst", type=float, default=0.01)
    parser.add_argument("--probe-time-scale", type=float, default=None)
    args = parser.parse_args()
    extra = {k: v for k, v in (("probe_hold", args.probe_hold),
                               ("probe_time_scale", args.probe_time_scale)) if v is not None}
    seeds = range(args.first_seed, args.first_seed + args.count)
    errors = agreement(seeds=seeds, contact_timeconst=args.contact_timeconst, **extra)
    for name, e in errors.items():
        ok = np.isfinite(e)
        quantiles = np.percentile(np.abs(e[ok]), [50, 75, 95]) if ok.any() else [np.nan] * 3
        print(f"{name:5s} identified {ok.sum()}/{ok.size}  |model/oracle - 1| median "
              f"{quantiles[0]:.3f}  p75 {quantiles[1]:.3f}  p95 {quantiles[2]:.3f}  "
              f"within 4 % {np.mean(np.abs(e) < 0.04):.0%}  ratios {np.round(1 + e, 3)}")
