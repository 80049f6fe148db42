"""mu's slipping level freed of the bias sensor noise puts into it: simulation-extrapolation.

With sensor noise the slip probe reads mu as the level each half-spoon's force ratio sits at
while its face slips (:data:`estimators.slip_level.SLIP_ENVELOPES`, ``per_blade_slipping``):
the
mean of the samples above the level less ``SLIPPING_TAIL`` noise sds.  Noise spreads the
sticking samples just below mu into that window too, so the level reads low, and the more
so the larger the noise: on the 512 tuning foods with 1 % noise mu came out 1.1 % low on
average (up to 6 % on some foods read within 0.2 % without noise).

SIMEX (simulation-extrapolation, Cook and Stefanski 1994, J. Am. Stat. Assoc. 89:1314)
measures that bias on the trace itself: it adds more noise of the sensor's own kind
(``lambda`` times its variance, from the forces before the blades touch) to copies of the
recorded forces, reads the level of each copy as the probe reads the trace, and
extrapolates the mean level against the noise's sd, ``sqrt(1 + lambda)`` times the
sensor's, back to zero noise.  The bias grows about linearly with the noise's sd (the
window below the level is ``SLIPPING_TAIL`` sds wide), so the extrapolation is a straight
line in the sd.  Its extra randomness is drawn from its own seeded generator, so a reading
is reproducible and leaves the caller's noise draws alone.

:func:`slipping_levels` reads many copies at once (one row each); it returns, row by row,
the level :func:`estimators.slip_level.read_mu` reads from one trace with noise (NaN where
the faces do not both grip on 5 samples, where read_mu falls back to the summed forces'
envelope), which the tests check against the one-trace code.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

SIDES = ("left", "right")
FORCES = tuple(f"{kind}_{side}" for side in SIDES for kind in ("normal", "tangential"))


@dataclass(frozen=True)
class LevelRule:
    """How a slipping level is read (the constants of :mod:`estimators.slip_level`).

    Attributes:
        quantile: the envelope's quantile of the force ratio (``ENVELOPE_QUANTILE``).
        noise_z: the standard normal's ``quantile`` quantile (``NOISE_QUANTILE_Z``).
        tail: noise sds below the level still read as slipping (``SLIPPING_TAIL``).
        iterations: refinements of the level (``SLIPPING_ITERATIONS``).
        min_share: the least share of its largest normal force a half-spoon must press
            with for a sample to be read (``NOISY_SLIP_MIN_SHARE``).
    """

    quantile: float
    noise_z: float
    tail: float
    iterations: int
    min_share: float


def _rowwise_max(x: np.ndarray, mask: np.ndarray) -> np.ndarray:
    return np.where(mask, x, -np.inf).max(axis=1)


def _pressed_samples(forces: dict[str, np.ndarray], rule: LevelRule) -> tuple[np.ndarray,
                                                                              np.ndarray]:
    """Each row's samples where the blades grip (the summed normal force above 5 % of its
    peak, each face above 5 % of its own) and, of those, the firmly pressed ones (each face
    at ``rule.min_share`` of its largest there, where at least 5 are); and whether a row
    has the 5 gripping samples a level needs."""
    normal = forces["normal_left"] + forces["normal_right"]
    both = normal > 0.05 * np.maximum(normal.max(axis=1), 1e-12)[:, None]
    for side in SIDES:
        n = forces[f"normal_{side}"]
        both &= n > 0.05 * np.maximum(n.max(axis=1), 1e-12)[:, None]
    enough = both.sum(axis=1) >= 5
    firm = both.copy()
    for side in SIDES:
        n = forces[f"normal_{side}"]
        firm &= n >= rule.min_share * _rowwise_max(n, both)[:, None]
    return np.where((firm.sum(axis=1) >= 5)[:, None], firm, both), enough


def slipping_shift(sd: float | np.ndarray, tail: float) -> float | np.ndarray:
    """How far the mean of normal samples of sd ``sd`` above their mean less ``tail`` sds
    sits above that mean, ``sd phi(tail) / Phi(tail)``: what the slipping level takes off
    the mean of the samples it reads (one trace's or, elementwise, many copies')."""
    return sd * math.exp(-0.5 * tail * tail) / math.sqrt(2 * math.pi) / (
        0.5 * (1.0 + math.erf(tail / math.sqrt(2.0))))


def _rowwise_quantile(x: np.ndarray, q: float) -> np.ndarray:
    """Each row's ``q`` quantile of its finite entries (NaN elsewhere), interpolated
    linearly as :func:`numpy.quantile` does; NaN for a row with none (faster than
    :func:`numpy.nanquantile` along an axis)."""
    s = np.sort(x, axis=1)  # NaN last
    count = np.isfinite(x).sum(axis=1)
    pos = q * np.maximum(count - 1, 0)
    lo = np.floor(pos).astype(int)
    hi = np.minimum(lo + 1, np.maximum(count - 1, 0))
    rows = np.arange(x.shape[0])
    a, b = s[rows, lo], s[rows, hi]
    out = a + (pos - lo) * (b - a)
    return np.where(count > 0, out, np.nan)


def _face_levels(n: np.ndarray, t: np.ndarray, read: np.ndarray, sd_n: np.ndarray,
                 sd_t: np.ndarray, rule: LevelRule) -> np.ndarray:
    """One face's slipping level per row, from its samples ``read``."""
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(read, np.abs(t) / n, np.nan)
        sd_ratio = np.hypot(sd_t[:, None], ratio * sd_n[:, None]) / n
    envelope = _rowwise_quantile(ratio, rule.quantile)
    sd = _rowwise_quantile(np.where(read, sd_ratio, np.nan), 0.5)
    c = rule.tail
    shift = slipping_shift(sd, c)
    level = envelope - rule.noise_z * sd
    active = sd > 0
    for _ in range(rule.iterations):
        with np.errstate(invalid="ignore"):
            top = read & (ratio > (level - c * sd)[:, None])
        count = top.sum(axis=1)
        active &= count >= 3
        mean = np.where(top, ratio, 0.0).sum(axis=1) / np.maximum(count, 1)
        level = np.where(active, mean - shift, level)
    return np.where(sd > 0, level, envelope)


def slipping_levels(forces: dict[str, np.ndarray], noise_sd: dict[str, np.ndarray],
                    rule: LevelRule) -> np.ndarray:
    """The lower of the two half-spoons' slipping levels, row by row.

    Args:
        forces: each of :data:`FORCES` as an (R, m) array: R copies of the late slide's m
            samples (finite: a non-finite sample is read as absent).
        noise_sd: each force's noise sd per row, (R,), finite and non-negative, with one
            positive per row (a face whose forces both read sd 0 reads its plain envelope,
            as the one-trace code does).
        rule: how the level is read.

    Returns:
        (R,) levels; NaN where a row has fewer than 5 samples where both faces grip.
    """
    read, enough = _pressed_samples(forces, rule)
    levels = [_face_levels(forces[f"normal_{side}"], forces[f"tangential_{side}"], read,
                           noise_sd[f"normal_{side}"], noise_sd[f"tangential_{side}"], rule)
              for side in SIDES]
    return np.where(enough, np.minimum(*levels), np.nan)


@dataclass(frozen=True)
class Simex:
    """The settings of the extrapolation.

    Attributes:
        lambdas: the added noise variances, in units of the sensor's: at least two
            distinct positive numbers.
        replicates: noisy copies read at each of them (at least 1).
        seed: the copies' generator's seed (the same for every slide: a reading depends on
            its trace alone).

    Raises:
        ValueError: settings outside those.
    """

    lambdas: tuple[float, ...] = (0.5, 1.0, 1.5, 2.0)
    replicates: int = 10
    seed: int = 20261201

    def __post_init__(self) -> None:
        lams = tuple(self.lambdas)
        if not (all(isinstance(v, int | float) and not isinstance(v, bool)
                    and math.isfinite(v) and v > 0 for v in lams) and len(set(lams)) >= 2):
            raise ValueError(f"Simex lambdas must be at least two distinct positive numbers, "
                             f"got {self.lambdas!r}")
        if not (isinstance(self.replicates, int) and not isinstance(self.replicates, bool)
                and self.replicates >= 1):
            raise ValueError(f"Simex replicates must be an integer >= 1, got {self.replicates!r}")
        if not (isinstance(self.seed, int) and not isinstance(self.seed, bool) and self.seed >= 0):
            raise ValueError(f"Simex seed must be an integer >= 0, got {self.seed!r}")


def simex_level(forces: dict[str, np.ndarray], noise_sd: dict[str, float], level: float,
                rule: LevelRule, simex: Simex = Simex()) -> float | None:
    """The noise-free slipping level extrapolated from ``level``, the one read from the
    recorded late slide ``forces`` (each of :data:`FORCES`, (m,), finite) with sensor noise
    of sd ``noise_sd`` per force (finite, at least one positive; a force read without
    noise gets none added); None where fewer than two of the added noise levels gave a
    level (the copies lost their grip).

    Raises:
        ValueError: forces that are not finite 1-D arrays of one length, or noise sds that
            are not finite and non-negative with one positive.
    """
    arrays = [np.asarray(forces[k], dtype=float) for k in FORCES]
    if not (all(a.ndim == 1 and a.size == arrays[0].size for a in arrays)
            and all(np.isfinite(a).all() for a in arrays)):
        raise ValueError("simex_level needs each force as a finite 1-D array, all of one "
                         "length")
    sds = [float(noise_sd[k]) for k in FORCES]
    if not (all(math.isfinite(v) and v >= 0 for v in sds) and max(sds) > 0):
        raise ValueError(f"simex_level needs finite, non-negative noise sds with one positive, "
                         f"got {dict(zip(FORCES, sds, strict=True))}")
    levels = _copies_levels(forces, noise_sd, rule, simex)
    sds, means = [1.0], [level]
    for lam, read in zip(simex.lambdas, levels, strict=True):
        read = read[np.isfinite(read)]
        if read.size:
            sds.append(math.sqrt(1.0 + lam))
            means.append(float(read.mean()))
    if len(sds) < 3:
        return None
    return float(np.polyfit(sds, means, 1)[1])  # the line's value at zero noise


def _copies_levels(forces: dict[str, np.ndarray], noise_sd: dict[str, float], rule: LevelRule,
                   simex: Simex) -> np.ndarray:
    """The slipping levels of ``simex.replicates`` noisy copies of the trace at each of
    ``simex.lambdas``, (lambdas, replicates): every copy read in one
    :func:`slipping_levels` call (its rows are read apart, so batching changes no level),
    its noise drawn as one block in the order a draw per lambda and force would take it."""
    n_lam, reps = len(simex.lambdas), simex.replicates
    m = next(iter(forces.values())).size
    draws = np.random.default_rng(simex.seed).standard_normal((n_lam, len(FORCES), reps, m))
    scale = np.sqrt(np.asarray(simex.lambdas, dtype=float))
    copies, sd = {}, {}
    for j, k in enumerate(FORCES):
        added = draws[:, j] * (scale * noise_sd[k])[:, None, None]
        copies[k] = (forces[k][None, None, :] + added).reshape(n_lam * reps, m)
        sd[k] = np.repeat(np.sqrt(1.0 + np.asarray(simex.lambdas)) * noise_sd[k], reps)
    return slipping_levels(copies, sd, rule).reshape(n_lam, reps)
