"""Tests of the induced-slippage friction estimator."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose

from estimators.errors import EstimationError
from estimators.friction import estimate_friction

MUS = [0.1, 0.2, 0.3, 0.5]


def make_slide(
    mu: float,
    seed: int = 0,
    fs: float = 100.0,
    noise: float = 0.014,
    tau: float = 0.4,
    ar: float = 0.0,
) -> tuple[np.ndarray, ...]:
    """PAPER's friction protocol: gravity 1 s, clamp to contact by 11 s, slide 11-21 s.

    During the clamp the half-spoons hold the food statically at T/N = 0.3 mu (a steady but
    sub-mu plateau, longer than the slide); at 11 s the slide starts and T/N rises to mu with
    an oscillating overshoot (time constant ``tau``). Normal forces differ between sides and
    wander slowly; noise (N) is white, or AR(1) with coefficient ``ar``.
    """
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, 21.0, 1.0 / fs)
    ramp = np.where(t < 1.0, 0.0, np.minimum((t - 1.0) / 2.0, 1.0))
    n_left = 0.8 * ramp + 0.05 * np.sin(0.7 * t) * (t > 3.0)
    n_right = 0.6 * ramp
    s = np.maximum(t - 11.0, 0.0)
    decay = np.exp(-s / tau)
    ratio = np.where(
        t < 11.0, 0.3 * mu, mu * (1.0 - 0.7 * decay) + 0.15 * mu * decay * np.sin(6.0 * s)
    )

    def noise_(scale: float) -> np.ndarray:
        e = rng.standard_normal(t.size)
        if ar:
            from scipy.signal import lfilter

            e = lfilter([np.sqrt(1 - ar**2)], [1.0, -ar], e)
        return scale * e

    return (
        t,
        n_left + noise_(noise),
        -ratio * n_left + noise_(noise * mu),  # sign of the tangential force is ignored
        n_right + noise_(noise),
        ratio * n_right + noise_(noise * mu),
    )


@pytest.mark.parametrize("mu", MUS)
def test_recovers_mu_within_1_percent(mu: float) -> None:
    covered = 0
    for seed in range(20):
        est = estimate_friction(*make_slide(mu, seed))
        assert_allclose(est.mu, mu, rtol=0.01)
        assert est.reliable, est.warnings
        # The static clamp plateau (0.3 mu) must never be taken for the slide.
        assert est.window[0] > 11.0
        covered += est.interval[0] <= mu <= est.interval[1]
    assert covered >= 17  # 95 % intervals


@pytest.mark.parametrize("mu", MUS)
def test_noise_free_is_exact(mu: float) -> None:
    est = estimate_friction(*make_slide(mu, noise=0.0))
    assert_allclose([est.mu, est.mu_left, est.mu_right], mu, rtol=1e-6)


def test_autocorrelated_noise_interval_is_widened() -> None:
    mu = 0.3
    covered = 0
    for seed in range(20):
        est = estimate_friction(*make_slide(mu, seed, ar=0.8))
        assert_allclose(est.mu, mu, rtol=0.01)
        assert est.n_effective < 0.5 * est.n_samples
        covered += est.interval[0] <= mu <= est.interval[1]
    assert covered >= 17


def test_slide_start_restricts_the_search() -> None:
    est = estimate_friction(*make_slide(0.2, 3), slide_start=11.0)
    assert est.window[0] >= 11.0
    assert_allclose(est.mu, 0.2, rtol=0.01)


def test_normal_force_zero_raises() -> None:
    t, nl, tl, nr, tr = make_slide(0.2, 0)
    after = t >= 11.0
    nl[after] = 0.0
    nr[after] = 0.0
    with pytest.raises(EstimationError, match="normal force ~0"):
        estimate_friction(t, nl, tl, nr, tr, slide_start=11.0)
    z = np.zeros_like(t)
    with pytest.raises(EstimationError, match="normal force ~0"):
        estimate_friction(t, z, tl, z, tr)


def test_no_plateau_raises() -> None:
    t = np.arange(0.0, 10.0, 0.01)
    n = np.ones_like(t)
    ramping = 0.05 * t + 0.02 * np.sin(3.0 * t) ** 2  # ratio that keeps changing
    with pytest.raises(EstimationError, match="never plateaus"):
        estimate_friction(t, n, ramping * n, n, ramping * n)


@pytest.mark.parametrize(
    ("mutate", "match"),
    [
        (lambda a: [x[:10] for x in a], "too short"),
        (lambda a: [a[0], a[1][:-1], *a[2:]], "mismatched lengths.*'normal_left'"),
        (
            lambda a: [a[0], a[1], a[2], a[3], np.where(a[0] > 15, np.nan, a[4])],
            "'tangential_right' has .* non-finite",
        ),
        (lambda a: [a[0], np.where(a[0] > 15, np.inf, a[1]), *a[2:]], "'normal_left'.*non-finite"),
        (lambda a: [a[0][::-1], *a[1:]], "unsorted"),
        (lambda a: [np.round(a[0], 1), *a[1:]], "repeated"),
    ],
)
def test_bad_inputs_raise(mutate, match: str) -> None:
    with pytest.raises(EstimationError, match=match):
        estimate_friction(*mutate(list(make_slide(0.2))))


@pytest.mark.parametrize("share_nan", [0.0, 0.3, 0.9, 1.0])
def test_the_running_median_is_numpys_nanmedian(share_nan: float) -> None:
    """The spike filter's running median is numpy's nanmedian of each centred window, bit
    for bit, with NaN gaps (odd and even counts of numbers in a window) and empty windows."""
    import warnings

    from estimators.friction import _running_median

    rng = np.random.default_rng(int(10 * share_nan))
    for n in (1, 2, 5, 7, 300):
        x = rng.normal(0.4, 0.05, n)
        x[rng.random(n) < share_nan] = np.nan
        pad = np.concatenate((np.full(2, np.nan), x, np.full(2, np.nan)))
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)  # an all-NaN window
            want = np.nanmedian(np.lib.stride_tricks.sliding_window_view(pad, 5), axis=1)
        np.testing.assert_array_equal(_running_median(x, 5), want)
