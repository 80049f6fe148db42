"""Friction coefficient ``mu`` between half-spoon and food by induced slippage.

The clamped food is pushed against the plate while the closed half-spoons keep moving, so the
half-spoons slide on the food. By Coulomb's law ``|T| <= mu |N|`` for the tangential ``T`` and
normal ``N`` contact forces (N) on a half-spoon, with equality only while it slides: the ratio
``T/N`` rises through an onset transient and then plateaus at ``mu`` during steady sliding.

:func:`estimate_friction` finds that plateau automatically -- the runs of samples where the
rolling standard deviation of the combined ratio ``(|T_L| + |T_R|) / (|N_L| + |N_R|)`` is at the
noise level, taking the run with the highest level (a static, sub-``mu`` plateau before the slide
is therefore never chosen) -- and returns the force-weighted ratio over it with a 95 % interval
whose sample size is corrected for autocorrelation (AR(1) effective sample size).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.stats import t as student_t

from estimators.errors import EstimationError, check_traces, optional_real, real

__all__ = ["MIN_SAMPLES", "FrictionEstimate", "estimate_friction"]

# the fewest samples of a slide (from slide_start on) that the plateau test reads
MIN_SAMPLES = 20


@dataclass
class FrictionEstimate:
    """Friction coefficient from one induced-slippage run.

    Attributes:
        mu: friction coefficient (dimensionless), both half-spoons combined.
        interval: 95 % interval of ``mu``.
        window: ``(t_begin, t_end)`` of the steady-slide samples used, s.
        n_samples: samples in the window.
        n_effective: autocorrelation-corrected sample size.
        mu_left, mu_right: per half-spoon ratios over the same window.
        reliable: False when the number should not be trusted (see ``warnings``).
        warnings: human-readable reasons.
    """

    mu: float
    interval: tuple[float, float]
    window: tuple[float, float]
    n_samples: int
    n_effective: float
    mu_left: float
    mu_right: float
    reliable: bool = True
    warnings: list[str] = field(default_factory=list)


def _rolling(x: NDArray[np.float64], w: int) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Mean and sd of every length-``w`` window of ``x`` (``len(x) - w + 1`` values)."""
    c1 = np.concatenate(([0.0], np.cumsum(x)))
    c2 = np.concatenate(([0.0], np.cumsum(x * x)))
    s1 = c1[w:] - c1[:-w]
    s2 = c2[w:] - c2[:-w]
    mean = s1 / w
    var = np.maximum(s2 / w - mean * mean, 0.0)
    return mean, np.sqrt(var)


def _running_median(x: NDArray[np.float64], k: int) -> NDArray[np.float64]:
    """Centred running median of odd length ``k`` ignoring NaN (edges use what exists; NaN
    where a window has no number): each window sorted (NaN last), then its middle number,
    or the mean of its middle two, as :func:`numpy.nanmedian` gives (bit for bit, at a
    quarter of its cost on a slide's trace)."""
    h = k // 2
    pad = np.concatenate((np.full(h, np.nan), x, np.full(h, np.nan)))
    win = np.sort(np.lib.stride_tricks.sliding_window_view(pad, k), axis=1)
    count = k - np.isnan(win).sum(axis=1)
    rows = np.arange(win.shape[0])
    lo = np.maximum(count - 1, 0) // 2
    hi = np.where(count % 2 == 1, lo, count // 2)
    median = (win[rows, lo] + win[rows, hi]) / 2
    return np.where(count > 0, np.where(count % 2 == 1, win[rows, lo], median), np.nan)


def _runs(mask: NDArray[np.bool_]) -> list[tuple[int, int]]:
    """Half-open ``[start, stop)`` index ranges of the True runs of ``mask``."""
    m = np.concatenate(([False], mask, [False])).astype(np.int8)
    d = np.diff(m)
    return list(zip(np.flatnonzero(d == 1).tolist(), np.flatnonzero(d == -1).tolist(), strict=True))


def estimate_friction(
    t: ArrayLike,
    normal_left: ArrayLike,
    tangential_left: ArrayLike,
    normal_right: ArrayLike,
    tangential_right: ArrayLike,
    slide_start: float | None = None,
    window: int | None = None,
    stability: float = 2.5,
    min_normal: float = 1e-3,
) -> FrictionEstimate:
    """Estimate ``mu`` from the contact forces on both half-spoons during an induced slide.

    Args:
        t: times, s (strictly increasing).
        normal_left, tangential_left, normal_right, tangential_right: contact forces, N (signs
            are ignored: magnitudes are used).
        slide_start: time (s) the slide starts, if known; earlier samples are ignored.
        window: rolling window (samples) for the plateau test; default ``len/20`` in [5, 200].
        stability: a window is steady when its ratio sd is below ``stability`` times the
            sample-to-sample noise sd of the ratio.
        min_normal: smallest total normal force (N) counted as contact.

    Returns:
        A :class:`FrictionEstimate`.

    Raises:
        EstimationError: bad traces (too short, mismatched, NaN/inf, unsorted time), normal force
            ~0 where the slide should be, no steady plateau of the ratio, an option that is not
            a real number, or a ``window`` that is not a whole number of samples in
            ``[3, len/2]``.
    """
    slide_start = optional_real("slide_start", slide_start)
    stability, min_normal = real("stability", stability), real("min_normal", min_normal)
    if slide_start is not None and not math.isfinite(slide_start):
        raise EstimationError(f"slide_start must be a finite time, s, got {slide_start!r}")
    if not (math.isfinite(min_normal) and min_normal >= 0.0):
        raise EstimationError(f"min_normal must be a finite force >= 0 N, got {min_normal!r}")
    forces = _slide_forces(
        t, normal_left, tangential_left, normal_right, tangential_right, slide_start
    )
    valid, ratio, n_scale = _contact_ratio(forces, min_normal)
    w = _window_length(window, forces.t.size)
    sigma, level, noise_floor = _ratio_noise(ratio, valid, n_scale)
    good = valid & ~_spikes(ratio, valid, sigma, level)
    mean_w, sd_w, full_w = _window_stats(ratio, valid, good, w)
    # Within-window noise: 2nd differences under-read correlated noise, so also use the median
    # rolling sd (plateaus -- static and sliding -- fill most of a run).
    if full_w.any():
        noise_floor = max(noise_floor, float(np.median(sd_w[full_w])))
    steady_w = full_w & (sd_w <= stability * noise_floor)
    a, b = _highest_plateau(steady_w, mean_w, full_w, w, noise_floor, stability)
    i0, i1 = _trim_onset(ratio, good, a, b, w)
    sel = np.arange(i0, i1)[good[i0:i1]]
    _reject_drift(forces.t[sel], ratio[sel])
    return _coulomb_estimate(forces, sel, (float(forces.t[i0]), float(forces.t[i1 - 1])), w)


@dataclass(frozen=True)
class _SlideForces:
    """Contact-force magnitudes (N) from the slide start on, and both half-spoons' totals."""

    t: NDArray[np.float64]
    normal_left: NDArray[np.float64]
    tangential_left: NDArray[np.float64]
    normal_right: NDArray[np.float64]
    tangential_right: NDArray[np.float64]
    normal: NDArray[np.float64]
    tangential: NDArray[np.float64]


def _slide_forces(
    t: ArrayLike,
    normal_left: ArrayLike,
    tangential_left: ArrayLike,
    normal_right: ArrayLike,
    tangential_right: ArrayLike,
    slide_start: float | None,
) -> _SlideForces:
    """Checked force magnitudes, cut to ``t >= slide_start`` (signs carry no information)."""
    tt, tr = check_traces(
        t,
        min_samples=MIN_SAMPLES,
        normal_left=normal_left,
        tangential_left=tangential_left,
        normal_right=normal_right,
        tangential_right=tangential_right,
    )
    nl, tl = np.abs(tr["normal_left"]), np.abs(tr["tangential_left"])
    nr, tgr = np.abs(tr["normal_right"]), np.abs(tr["tangential_right"])
    if slide_start is not None:
        keep = tt >= slide_start
        if keep.sum() < MIN_SAMPLES:
            raise EstimationError(
                f"trace too short after slide_start={float(slide_start):.4g} s: {int(keep.sum())} "
                f"samples, at least {MIN_SAMPLES} are needed"
            )
        tt, nl, tl, nr, tgr = tt[keep], nl[keep], tl[keep], nr[keep], tgr[keep]
    return _SlideForces(tt, nl, tl, nr, tgr, nl + nr, tl + tgr)


def _contact_ratio(
    forces: _SlideForces, min_normal: float
) -> tuple[NDArray[np.bool_], NDArray[np.float64], float]:
    """The samples in contact, the combined ratio ``T/N`` (NaN elsewhere) and the largest N.

    A sample is in contact when its total normal force exceeds 5 % of the largest (and
    ``min_normal``): near-zero N would make the ratio noise.
    """
    n_tot, t_tot = forces.normal, forces.tangential
    n_scale = float(np.max(n_tot))
    if not n_scale > min_normal:
        raise EstimationError(
            f"normal force ~0 in the slip window: max |N_left| + |N_right| = {n_scale:.3g} N "
            f"(<= min_normal={min_normal:.3g} N)"
        )
    valid = n_tot > max(0.05 * n_scale, min_normal)
    ratio = np.where(valid, t_tot / np.where(valid, n_tot, 1.0), np.nan)
    return valid, ratio, n_scale


def _window_length(window: int | None, n: int) -> int:
    """The rolling window in samples: ``window`` checked, or ``n/20`` clipped to [5, 200]."""
    if window is not None:
        wv = real("window", window)
        if not (math.isfinite(wv) and wv == int(wv)):
            raise EstimationError(f"window must be a whole number of samples, got {window!r}")
    w = int(window) if window is not None else int(np.clip(n // 20, 5, 200))
    if w < 3 or w > n // 2:
        raise EstimationError(f"rolling window {w} samples is invalid for {n} samples")
    return w


def _ratio_noise(
    ratio: NDArray[np.float64], valid: NDArray[np.bool_], n_scale: float
) -> tuple[float, float, float]:
    """Sample-to-sample noise sd of the ratio, its median level and the noise floor.

    The sd is the MAD of 2nd differences (blind to smooth trends); the floor keeps it above
    rounding for noise-free traces.
    """
    rv = ratio[valid]
    if rv.size < MIN_SAMPLES:
        raise EstimationError(
            f"normal force ~0 in the slip window: only {rv.size} samples have normal force "
            f"above max(5 % of its maximum {n_scale:.3g} N, min_normal)"
        )
    d2 = np.diff(rv, 2)
    sigma = float(1.4826 * np.median(np.abs(d2 - np.median(d2))) / math.sqrt(6.0))
    level = float(np.median(rv))
    return sigma, level, max(sigma, 1e-6 * abs(level), 1e-12)


def _spikes(
    ratio: NDArray[np.float64], valid: NDArray[np.bool_], sigma: float, level: float
) -> NDArray[np.bool_]:
    """Samples far (> 8 sd) from their 5-sample running median.

    Isolated spikes (a contact chattering for a sample or two) would split a steady slide into
    fragments, so they are dropped (and a window still counts as full with up to 5 % dropped).
    """
    n = ratio.size
    spike = np.zeros(n, dtype=bool)
    if n >= 5:
        rm = _running_median(np.where(valid, ratio, np.nan), 5)
        dev = np.abs(ratio - rm)
        spike = valid & np.isfinite(rm) & (dev > 8.0 * max(sigma, 1e-9 * abs(level)))
    return spike


def _window_stats(
    ratio: NDArray[np.float64], valid: NDArray[np.bool_], good: NDArray[np.bool_], w: int
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.bool_]]:
    """Mean and sd of the ratio's good samples in every length-``w`` window, and which
    windows are full (all in contact, at least 95 % of the samples good)."""
    r0 = np.where(good, ratio, 0.0)
    cnt, _ = _rolling(good.astype(np.float64), w)
    sum1, _ = _rolling(r0, w)
    sum2, _ = _rolling(r0 * r0, w)
    safe = np.maximum(cnt, 1e-12)
    mean_w = sum1 / safe
    sd_w = np.sqrt(np.maximum(sum2 / safe - mean_w * mean_w, 0.0))
    ok_w, _ = _rolling(valid.astype(np.float64), w)
    full_w = (ok_w > 1.0 - 1e-12) & (cnt >= 0.95 - 1e-12)
    return mean_w, sd_w, full_w


def _highest_plateau(
    steady_w: NDArray[np.bool_],
    mean_w: NDArray[np.float64],
    full_w: NDArray[np.bool_],
    w: int,
    noise_floor: float,
    stability: float,
) -> tuple[int, int]:
    """Window starts ``[a, b)`` of the sliding plateau: the longest run at the highest level.

    Coulomb: T/N equals mu only while sliding and is below it otherwise, hence the highest
    plateau.  Runs at that level (within noise) separated by short gaps are one plateau: they
    are merged and the longest taken, so that noise cannot pick a short high fragment.
    """
    runs = [(a, b) for a, b in _runs(steady_w) if b - a >= max(w // 2, 2)]
    if not runs:
        raise EstimationError(
            "no steady slip: the tangential/normal ratio never plateaus (rolling sd never falls "
            f"to {stability} x its noise sd {noise_floor:.3g})"
        )
    levels = np.array([float(np.median(mean_w[a:b])) for a, b in runs])
    top = float(levels.max())
    tol = 0.05 * abs(top) + 3.0 * noise_floor / math.sqrt(w)
    cand = [r for r, lv in zip(runs, levels, strict=True) if lv >= top - tol]
    merged = [cand[0]]
    for a, b in cand[1:]:
        pa, pb = merged[-1]
        if a - pb <= w and bool(np.all(full_w[pb:a])):
            merged[-1] = (pa, b)
        else:
            merged.append((a, b))
    return max(merged, key=lambda r: r[1] - r[0])


def _trim_onset(
    ratio: NDArray[np.float64], good: NDArray[np.bool_], a: int, b: int, w: int
) -> tuple[int, int]:
    """Sample range ``[i0, i1)`` of the plateau's windows with the onset transient's tail cut.

    Window starts a..b-1 cover samples a .. b-1+w-1; half a window is trimmed at the front,
    where the first steady windows can still hold the tail of the transient, then leading
    half-window blocks whose mean still differs (> 3 sd of a block mean) from the rest.
    """
    i0 = min(a + w // 2, b - 1)
    i1 = b - 1 + w
    bs = max(w // 2, 2)
    while i1 - i0 >= 4 * bs:
        head = ratio[i0 : i0 + bs][good[i0 : i0 + bs]]
        rest = ratio[i0 + bs : i1][good[i0 + bs : i1]]
        if head.size < 2 or rest.size < 2:
            break
        sd_r = float(np.std(rest, ddof=1))
        if abs(float(head.mean()) - float(rest.mean())) <= 3.0 * sd_r / math.sqrt(bs):
            break
        i0 += bs
    return i0, i1


def _reject_drift(tw: NDArray[np.float64], rw: NDArray[np.float64]) -> None:
    """Refuse a ratio that keeps drifting across the window: a steady slide has no trend."""
    slope, icpt = np.polyfit(tw - tw[0], rw, 1)
    span = float(tw[-1] - tw[0])
    drift = abs(float(slope)) * span
    fit_sd = float(np.std(rw - (icpt + slope * (tw - tw[0])), ddof=2)) if rw.size > 2 else 0.0
    se_drift = fit_sd * math.sqrt(12.0 / max(rw.size, 1))  # se of slope * span, white noise
    if drift > 0.02 * abs(float(np.mean(rw))) and drift > 4.0 * se_drift:
        raise EstimationError(
            f"no steady slip: the tangential/normal ratio never plateaus (it drifts by "
            f"{drift:.3g} over the steadiest window t=[{tw[0]:.6g}, {tw[-1]:.6g}] s)"
        )


def _coulomb_estimate(
    forces: _SlideForces, sel: NDArray[np.intp], window: tuple[float, float], w: int
) -> FrictionEstimate:
    """The force-weighted ratio over the samples ``sel``, its 95 % interval and warnings.

    The interval's sample size is corrected for the residuals' lag-1 autocorrelation (AR(1)
    effective sample size), since force noise is rarely white at the recording rate.
    """
    N_w, T_w = forces.normal[sel], forces.tangential[sel]
    mu = float(T_w.sum() / N_w.sum())
    e = T_w - mu * N_w
    m = e.size
    ec = e - e.mean()
    denom = float(np.dot(ec, ec))
    rho = float(np.dot(ec[1:], ec[:-1]) / denom) if denom > 0 else 0.0
    rho = min(max(rho, 0.0), 0.99)
    n_eff = max(m * (1.0 - rho) / (1.0 + rho), 2.0)
    s_e = float(np.std(e, ddof=1))
    se_mu = s_e * math.sqrt(m / n_eff) * math.sqrt(m) / float(N_w.sum())
    q = float(student_t.ppf(0.975, max(n_eff - 1.0, 1.0)))
    interval = (mu - q * se_mu, mu + q * se_mu)
    nl, nr = forces.normal_left[sel], forces.normal_right[sel]
    mu_l = float(forces.tangential_left[sel].sum() / nl.sum()) if nl.sum() > 0 else math.nan
    mu_r = float(forces.tangential_right[sel].sum() / nr.sum()) if nr.sum() > 0 else math.nan
    warns: list[str] = []
    reliable = True
    if m < 2 * w:
        warns.append(f"steady-slide window is short ({m} samples < 2 x rolling window {w})")
        reliable = False
    if q * se_mu > 0.05 * abs(mu):
        warns.append(f"mu is poorly determined (95 % half-width {q * se_mu:.3g} vs {mu:.3g})")
        reliable = False
    if np.isfinite(mu_l) and np.isfinite(mu_r) and abs(mu_l - mu_r) > 0.1 * mu:
        warns.append(
            f"half-spoons disagree: mu_left={mu_l:.4g}, mu_right={mu_r:.4g} (asymmetric contact?)"
        )
    return FrictionEstimate(
        mu=mu,
        interval=(float(interval[0]), float(interval[1])),
        window=window,
        n_samples=int(m),
        n_effective=float(n_eff),
        mu_left=mu_l,
        mu_right=mu_r,
        reliable=reliable,
        warnings=warns,
    )
