"""mu from a slide's recorded contact forces: each half-spoon's force ratio at the level it
slips at, the lower of the two, less the bias the sensor's noise puts into it.

Coulomb friction bounds each half-spoon's force ratio |F_t| / F_n by mu, and a face reaches
it while it slips.  :func:`read_mu` reads it from the forces alone (no simulator): the
simulated slip probe reads its slides through it (``fetch_env.probes.estimate_mu``) and
``food-fetch estimate --traces`` a robot's.  Its constants were chosen on the validation
harness's tuning foods' simulated slides; each comment below gives the evidence.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any, Literal

import numpy as np

from estimators.errors import EstimationError, check_traces, mapping
from estimators.friction import MIN_SAMPLES as FRICTION_MIN_SAMPLES
from estimators.friction import FrictionEstimate, estimate_friction
from estimators.slip_simex import FORCES as SLIP_FORCES
from estimators.slip_simex import LevelRule, Simex, simex_level, slipping_shift
from estimators.uncertainty import log_interval

__all__ = ["ENVELOPE_QUANTILE", "MU_SYSTEMATIC_SD", "NOISE_QUANTILE_Z", "NOISY_SLIP_MIN_SHARE",
           "SLIPPING_ITERATIONS", "SLIPPING_TAIL", "SLIP_ENVELOPES", "SLIP_FORCES",
           "SLIP_SIMEX", "SlipEnvelope", "read_mu"]

# How a slide's envelope reads the half-spoons' force ratios (read_mu's envelope; each kind
# and the evidence it was chosen on, below).
SlipEnvelope = Literal["sum", "per_blade", "per_blade_denoised", "per_blade_slipping",
                       "per_blade_simex"]
SLIP_ENVELOPES: tuple[SlipEnvelope, ...] = ("sum", "per_blade", "per_blade_denoised",
                                            "per_blade_slipping", "per_blade_simex")

# mu's systematic uncertainty (log sd) beyond what a slide reveals: the probes' (fetch_env.
# probes.PROBE_SYSTEMATIC_SD, where it is derived), added to every reading's interval.
MU_SYSTEMATIC_SD = 0.02

# slip probe: quantile of |F_t| / F_n taken as mu where the plateau is lower.  Coulomb bounds
# the ratio by mu and a stick-slipping piece reaches it only in its short slips, so a high
# quantile: on the 64 tuning foods ("measure" probes) 0.95 / 0.99 / 1.0 gave mu's median
# error 0.52 / 0.30 / 0.23 % and 95th percentile 7.0 / 5.2 / 5.2 %; 0.99, not the maximum,
# so that sensor noise cannot set it.
ENVELOPE_QUANTILE = 0.99


# How an envelope reads the two half-spoons (read_mu's envelope; the simulated probes'
# ProbeConfig.slip_envelope):
# "sum": the ratio of their summed forces; "per_blade": each half-spoon's own ratio, and the
# lower of the two envelopes, and likewise the lower of the two faces' plateaus.  Coulomb
# bounds each half-spoon's ratio by mu, and each reaches it whenever its own face slips, so
# the lower one reads mu unless both faces misread together.  What makes one face misread: a
# blade tip ploughing into a cube's face as the blades slide (a few contacts on the tip's
# edge, whose normal is tilted ~50 degrees from the face's, add their push to the tangential
# force; measured contact by contact on a 9 mm, 0.024 MPa cube whose summed ratio read mu
# +45 %).  Chosen on the 256 tuning foods (the committed uncalibrated "measure" runs, median /
# 95th percentile of |mu error|): "sum" 0.26 / 8.04 %, "per_blade" 0.09 / 4.09 % without
# noise; 2.06 / 9.46 % and 2.17 / 5.42 % with 1 % noise.  A lower quantile, the per-sample
# lower face, or smoothing the forces first did worse on the 95th percentile.
# "per_blade_denoised": per_blade's envelopes, each less the share of it that sensor noise
# adds: a ratio that sits at mu with white noise of sd s per sample has its
# ENVELOPE_QUANTILE quantile at mu + NOISE_QUANTILE_Z s, so that is taken off, with s from
# each half-spoon's force noise before the blades touch (the settle phase, where the true
# forces are zero; :func:`_settle_noise`).  Without noise it reads exactly as per_blade.  On
# the 512 tuning foods with 1 % noise (the "precise" slip probe) it moved mu's |error| from
# 3.7 / 14.5 % (median / 95th percentile; mean +4.8 %) to 1.8 / 8.6 % (mean -0.1 %).
# "per_blade_slipping": per_blade_denoised's envelope, refined to the level the ratio sits
# at while the face slips, read from every sample near it instead of one quantile: with
# noise the ratio's top samples are the slipping ones, spread by the noise (sd s) about mu,
# so mu is the mean of the samples above (mu - SLIPPING_TAIL s) less that truncated
# normal's shift (s phi(c) / Phi(c), c = SLIPPING_TAIL), iterated from the denoised
# envelope.  Without noise (s = 0) it reads exactly as per_blade.  On the 512 tuning foods
# with 1 % noise (benchmarks/slip_probe.py), mu's |error| (median / 90th / 95th percentile /
# max) from the precise probe's three slides went from 1.50 / 4.5 / 5.6 / 16 % to 0.77 /
# 2.8 / 4.1 / 19 % (foods past 1.4 %: 261 to 136; both read from every gripping sample,
# before NOISY_SLIP_MIN_SHARE); from one slide alone from 1.80 / 6.0 /
# 8.6 % to 0.95 / 6.3 / 11.6 %: a single slide's level misreads a few more foods badly,
# which the median of three mends.  On 256 of them, four noise draws each (three slides),
# with 1 % noise 1.50 / 4.5 / 5.9 % went to 0.76 / 3.0 / 4.9 %, with 0.3 %
# from 0.66 / 1.7 / 2.2 % to 0.33 / 1.2 / 1.8 %, with
# 3 % from 3.5 / 12 / 16 % to 1.7 / 6.6 / 9.4 % (the worst 76 % against 45 %; two draws
# each); c = 1.25 / 1.75 gave 0.73 / 2.9 / 6.8 % and 0.83 / 3.0 / 4.2 % with 1 % noise;
# smoothing the forces first biased mu low instead (mean -1.6 to -4.8 %).
# "per_blade_simex": per_blade_slipping's level less the bias that sensor noise puts into
# it, measured on the trace by simulation-extrapolation (estimators.slip_simex): copies of
# the slide with more noise of the sensor's own kind read lower, and their levels,
# extrapolated linearly in the noise's sd back to none, give the noise-free level.  Without
# noise it reads exactly as per_blade_slipping (and so as per_blade).  Chosen on the 512
# tuning foods' slides (precise probe, three slides, one 1 % noise draw each,
# uncalibrated; median / 90th / 95th percentile / max of |mu error|, mean, foods past
# 1.4 %): the slipping level 0.82 / 2.5 / 3.2 / 6.3 %, -1.1 %, 162; extrapolated from
# lambda 0.5, 1, 1.5 and 2 with 10 copies each 0.47 / 1.5 / 1.9 / 4.1 %, -0.36 %, 62; from
# lambda 1 and 3 with 5 or 10 copies 0.47 / 1.6 / 2.0 / 4.4 % and 0.42 / 1.5 / 1.9 / 4.3 %;
# extrapolated linearly in lambda instead of the sd 0.69 / 1.9 / 2.7 / 5.0 % (first 60
# foods, two draws: the bias grows with the sd, not the variance).  On the first 128 with
# 0.3 % noise 0.40 / 1.0 / 1.3 / 2.7 % went to 0.24 / 0.8 / 1.0 / 5.3 % (the 5.3 % a
# slippery cube whose noise-free reading is itself 1-6 % high: the extrapolation recovers
# the noise-free reading, not mu), with 3 % from 1.6 / 7.0 / 8.3 / 11.6 % (21 foods past
# 5 %) to 1.1 / 3.9 / 5.2 / 9.4 % (7 past 5 %).  With benchmarks/slip_probe.py's noise
# draws (512 tuning foods, 1 %): 0.87 / 2.7 / 3.1 / 6 %, mean -1.11 %, 154 foods past 1.4 %
# went to 0.44 / 1.5 / 2.0 / 4 %, -0.22 %, 55.


SLIP_SIMEX = Simex()
NOISE_QUANTILE_Z = 2.326  # the standard normal's ENVELOPE_QUANTILE (0.99) quantile
SLIPPING_TAIL = 1.5  # [noise sds] below the slipping level still read as slipping
SLIPPING_ITERATIONS = 5
# With sensor noise the noise-aware envelopes read only the samples where both half-spoons
# press with at least this share of their largest normal force over the late slide.  A
# ratio's noise grows as 1 / F_n, and a round piece that bounces between the blades passes
# through normal forces near zero many times a slide (a 16 mm sphere's: 0 to 0.7 N every
# ~15 ms, its ratio at mu throughout); its weakly pressed samples' noise is several times
# the median sd the envelope takes off, so their top read mu high (+16 %).  Chosen on the
# 256 first tuning foods' slides (precise probe, three slides, three 1 % noise draws each,
# 768 readings, uncalibrated; median / 95th percentile / max of |mu error|, readings past
# 5 %): all samples 0.83 / 5.6 / 16.1 %, 47; share 0.1 0.81 / 3.2 / 8.3 %, 7; 0.15 0.82 /
# 3.0 / 6.3 %, 3; 0.2 0.84 / 3.0 / 6.3 %, 3; 0.3 0.92 / 3.0 / 6.0 %, 3; 0.5 0.88 / 3.3 /
# 7.5 %, 7.  With 0.3 % noise (two draws) 0.34 / 1.6 / 4.0 % went to 0.38 / 1.5 / 4.0 %,
# with 3 % 1.67 / 10.7 / 42.7 % to 1.77 / 7.6 / 12.8 %.  On all 512 tuning foods (one draw,
# benchmarks/slip_probe.py) 0.77 / 2.8 / 4.1 / 19 % (90th percentile before the max; foods
# past 1.4 %: 136) went to 0.87 / 2.7 / 3.1 / 6 % (154), and the mean error from -0.3 to
# -1.1 %: the weak samples' upward noise had hidden a low bias, the sticking samples just
# below mu that the slipping level cannot tell from slipping ones within the noise.  Without
# noise nothing is dropped.
NOISY_SLIP_MIN_SHARE = 0.2


def read_mu(t: np.ndarray, forces: Mapping[str, np.ndarray], slide: np.ndarray,
            settle: np.ndarray | None, envelope: SlipEnvelope = "per_blade_simex",
            diagnostics: dict[str, float] | None = None
            ) -> tuple[float, list[str], tuple[float, float]]:
    """mu from a slide's recorded contact forces, with a 95 % interval: the simulated slip
    probe's reading, and a robot log's (``food-fetch estimate --traces``); raises
    :class:`EstimationError` when the trace cannot give it.

    Coulomb friction bounds the force ratio |F_t| / F_n by mu, and reaches it only while the
    blades slide.  A soft or round piece stick-slips under the blades (the ratio swings
    between ~0.05 and mu), and ``estimate_friction`` may then return a sticking plateau below
    mu; so mu is the larger of its estimate and the upper envelope of the ratio (its
    ``ENVELOPE_QUANTILE`` quantile over the last three quarters of the slide, where the
    blades grip; with ``envelope="per_blade"`` each half-spoon's, the lower of the two, and
    the lower of the two faces' plateaus; with ``"per_blade_denoised"`` (or
    ``"per_blade_slipping"``, refined to the slipping level, or ``"per_blade_simex"``, that
    level less the bias the noise leaves in it, :mod:`estimators.slip_simex`) those
    envelopes less what sensor noise adds, see :data:`SLIP_ENVELOPES`).  The interval adds,
    on the log scale, the estimator's own (noise) interval and what noise added to the
    envelope, the
    gap between the plateau and the envelope and between the two half-spoons (model error),
    and ``MU_SYSTEMATIC_SD``.  ``diagnostics`` (where given) receives the slide's
    (:func:`_mu_diagnostics`).

    Args:
        t: sample times [s], increasing.
        forces: each of :data:`SLIP_FORCES` [N], one sample per time: each half-spoon's
            normal force (pressing, positive) and tangential force along the slide.
        slide: which samples belong to the slide (boolean, one per sample).
        settle: which samples come before the blades touch the piece, where the forces'
            true value is zero, so that their spread is the sensor's noise (read by the
            noise-aware envelopes); None, or fewer than 5 samples, reads without that
            correction, with a warning.

    Raises:
        EstimationError: an unknown envelope; a force missing, or times and forces that
            :func:`estimators.errors.check_traces` refuses (at least 10 samples); a mask
            that is not a boolean array of one value per sample; no sample marked as the
            slide, or a slide that gives no mu.
    """
    t, forces, slide, settle = _checked_inputs(t, forces, slide, settle, envelope)
    if not slide.any():
        raise EstimationError("no sample is marked as the slide")
    idx = np.flatnonzero(slide)
    late = idx[len(idx) // 4:]
    normal = forces["normal_left"][late] + forces["normal_right"][late]
    tang = forces["tangential_left"][late] + forces["tangential_right"][late]
    grip = normal > 0.05 * max(float(normal.max()), 1e-12)
    if grip.sum() < 5:
        raise EstimationError("no steady grip during the slide (the blades lost the piece)")
    ratio = np.abs(tang[grip]) / normal[grip]
    warns: list[str] = []
    by_blade = envelope != "sum"
    noise_sd = None
    if envelope in ("per_blade_denoised", "per_blade_slipping", "per_blade_simex"):
        noise_sd = _settle_noise(settle, forces)
        if noise_sd is None:
            warns.append("fewer than 5 samples before the blades touch: the envelope is not "
                         "corrected for sensor noise")
    slipping = envelope in ("per_blade_slipping", "per_blade_simex")
    per_blade = (_per_blade_envelope(forces, late, grip, noise_sd, slipping=slipping)
                 if by_blade else None)
    if envelope == "per_blade_simex" and per_blade is not None and noise_sd is not None \
            and max(noise_sd.values()) > 0:
        # the noise share (per_blade[1], for mu's interval) stays the uncorrected level's:
        # the error model fitted on such readings sizes what the extrapolation leaves
        per_blade, why = _extrapolated(forces, late, SLIP_FORCES, noise_sd, per_blade)
        if why:
            warns.append(f"the slipping level's noise bias was not extrapolated ({why}): mu "
                         "read without the correction")
    if by_blade and per_blade is None:
        warns.append("fewer than 5 samples where both half-spoons grip: mu from the summed "
                     "forces' envelope")
    env, noise_share = ((float(np.quantile(ratio, ENVELOPE_QUANTILE)), 0.0)
                        if per_blade is None else per_blade)
    plateau, est = _plateau(t, forces, SLIP_FORCES, float(t[slide][0]), by_blade, warns)
    # Read at the slipping level (noise present), the envelope is already the level a
    # steady slide sits at, from the same samples as the plateau, so the plateau is no
    # second reading (on the 256 tuning foods with 1 % noise letting it override moved mu's
    # median |error| by 0.01 points and its 95th percentile not at all; on a synthetic,
    # perfectly steady slide the plateau is the steadier, sd 0.23 % against 0.29 %,
    # tests/test_slip_envelope.py).
    level_read = (slipping and per_blade is not None
                  and noise_sd is not None and max(noise_sd.values()) > 0)
    if np.isfinite(plateau) and plateau >= env and not level_read:
        mu = plateau
    else:
        mu = env
        if np.isfinite(plateau) and plateau < 0.98 * env:
            warns.append(f"estimate_friction's plateau {plateau:.3g} is below the ratio's "
                         f"envelope {env:.3g} (stick-slip): mu from the envelope")
    if not (np.isfinite(mu) and mu > 0):
        raise EstimationError(f"friction estimate is not finite and positive: {mu!r}")
    sd = math.hypot(_mu_sd_log(mu, est, env, noise_share), MU_SYSTEMATIC_SD)
    if diagnostics is not None:
        diagnostics.update(_mu_diagnostics(mu, est, env, ratio, float(grip.mean()),
                                           noise_share))
    return mu, warns, log_interval(mu, sd)


def _plateau(t: np.ndarray, f: dict[str, np.ndarray], keys: tuple[str, ...],
             slide_start: float, by_blade: bool, warns: list[str]
             ) -> tuple[float, FrictionEstimate | None]:
    """``estimate_friction``'s plateau of the slide (the lower half-spoon's where
    ``by_blade``) and its estimate, or NaN and None where it gives none (why, in ``warns``).
    A slide with fewer samples than its plateau test reads (``MIN_SAMPLES``; e.g. the
    environments' 0.15 s probe slide at a 10 ms step, 15 samples) is read from its envelope
    alone, without a warning."""
    if int(np.count_nonzero(t >= slide_start)) < FRICTION_MIN_SAMPLES:
        return math.nan, None
    try:
        est = estimate_friction(t, *(f[k] for k in keys), slide_start=slide_start)
    except (EstimationError, ArithmeticError) as exc:
        # Its plateau test is strict for a short slide (the ratio drifts by ~1 % as the
        # normal force relaxes).
        warns.append(f"estimate_friction: {exc}; mu from the ratio's envelope")
        return math.nan, None
    warns += list(est.warnings)
    plateau = float(est.mu)
    if by_blade and est.mu_left > 0 and est.mu_right > 0:
        plateau = min(float(est.mu_left), float(est.mu_right))
    return plateau, est


def _extrapolated(f: dict[str, np.ndarray], late: np.ndarray, keys: tuple[str, ...],
                  noise_sd: dict[str, float], per_blade: tuple[float, float]
                  ) -> tuple[tuple[float, float], str]:
    """``per_blade`` with its slipping level freed of the noise's bias by SIMEX
    (:func:`estimators.slip_simex.simex_level`), and "" ; or ``per_blade`` as it was and why
    not (forces that are not finite, copies of the slide that lost their grip, a level
    extrapolated to zero or below)."""
    if not all(np.isfinite(f[k][late]).all() for k in keys):
        return per_blade, "the late slide's forces are not all finite"
    level = simex_level({k: f[k][late] for k in keys}, noise_sd, per_blade[0], _level_rule(),
                        SLIP_SIMEX)
    if level is None:
        return per_blade, "noisier copies of the slide lost their grip"
    if not level > 0:
        return per_blade, f"it extrapolated to {level:.3g}"
    return (level, per_blade[1]), ""


def _per_blade_envelope(f: dict[str, np.ndarray], late: np.ndarray, grip: np.ndarray,
                        noise_sd: dict[str, float] | None = None, slipping: bool = False
                        ) -> tuple[float, float] | None:
    """The lower of the two half-spoons' ``ENVELOPE_QUANTILE`` envelopes of their own force
    ratio, over the late slide's samples where both grip (each above 5 % of its own peak),
    and the share of it that noise took off (0 without ``noise_sd``); None where fewer than
    5 such samples exist.  With ``noise_sd`` (each force trace's noise sd,
    :func:`_settle_noise`, some of it positive) only the firmly pressed samples are read
    (:func:`_firmly_pressed`) and each envelope is less ``NOISE_QUANTILE_Z`` times the median noise
    sd of its ratio (see :data:`SLIP_ENVELOPES`), and, with ``slipping``, refined to the
    ratio's slipping level (:func:`_slipping_level`); the larger of the two half-spoons'
    shares taken off is returned: a log-sd of mu's noise, for its interval."""
    both = grip.copy()
    sides = []
    for side in ("left", "right"):
        n, t = f[f"normal_{side}"][late], f[f"tangential_{side}"][late]
        both &= n > 0.05 * max(float(n.max()), 1e-12)
        sides.append((side, n, np.abs(t)))
    if both.sum() < 5:
        return None
    if noise_sd is not None and max(noise_sd.values()) > 0:
        both = _firmly_pressed(sides, both)
    envelopes, shares = [], [0.0]
    for side, n, t in sides:
        ratio = t[both] / n[both]
        env = float(np.quantile(ratio, ENVELOPE_QUANTILE))
        if noise_sd is not None:
            sd_ratio = np.hypot(noise_sd[f"tangential_{side}"],
                                ratio * noise_sd[f"normal_{side}"]) / n[both]
            s = float(np.median(sd_ratio))
            taken = NOISE_QUANTILE_Z * s
            if slipping and s > 0:
                taken = env - _slipping_level(ratio, env - taken, s)
            shares.append(taken / env if env > 0 else 0.0)
            env -= taken
        envelopes.append(env)
    return min(envelopes), max(shares)


def _firmly_pressed(sides: list[tuple[str, np.ndarray, np.ndarray]], both: np.ndarray
                    ) -> np.ndarray:
    """The samples of ``both`` where each half-spoon's normal force is at least
    :data:`NOISY_SLIP_MIN_SHARE` of its largest over ``both`` (where their ratios' noise is
    at most ~1 / share times the least); ``both`` itself where fewer than 5 are."""
    firm = both.copy()
    for _, n, _ in sides:
        firm &= n >= NOISY_SLIP_MIN_SHARE * float(n[both].max())
    return firm if firm.sum() >= 5 else both


def _slipping_level(ratio: np.ndarray, start: float, sd: float) -> float:
    """The level a force ratio sits at while its face slips, from its samples with noise
    of sd ``sd``: from ``start``, ``SLIPPING_ITERATIONS`` times the mean of the samples
    above the level less ``SLIPPING_TAIL`` sds, less the shift that cut puts into a
    normal's mean (``sd phi(c) / Phi(c)``); where fewer than 3 samples are that high, the
    level so far (see :data:`SLIP_ENVELOPES`)."""
    c = SLIPPING_TAIL
    shift = float(slipping_shift(sd, c))
    level = start
    for _ in range(SLIPPING_ITERATIONS):
        top = ratio[ratio > level - c * sd]
        if top.size < 3:
            break
        level = float(top.mean()) - shift
    return level


def _level_rule() -> LevelRule:
    """The slipping level's constants, as :mod:`estimators.slip_simex` reads many copies."""
    return LevelRule(quantile=ENVELOPE_QUANTILE, noise_z=NOISE_QUANTILE_Z, tail=SLIPPING_TAIL,
                     iterations=SLIPPING_ITERATIONS, min_share=NOISY_SLIP_MIN_SHARE)


def _settle_noise(settle: np.ndarray | None, f: dict[str, np.ndarray]
                  ) -> dict[str, float] | None:
    """Each force trace's sd over the ``settle`` samples, before the blades touch the food
    (its true forces are zero there, so what it reads is the sensor's noise); None where
    fewer than 5 such samples exist."""
    if settle is None or settle.sum() < 5:
        return None
    return {k: float(np.std(v[settle])) for k, v in f.items()}


def _mu_diagnostics(mu: float, est: Any, envelope: float, ratio: np.ndarray, grip: float,
                    noise_share: float = 0.0) -> dict[str, float]:
    """How steady the slide was, for the calibration's error model: whether
    estimate_friction found a plateau (``mu_plateau``), the log-gaps of its plateau to the
    envelope (``mu_gap``) and of the two half-spoons (``mu_lr``), its noise log-sd
    (``sd_noise_mu``, with the share of the envelope that sensor noise added, see
    :func:`_per_blade_envelope`), the spread of the force ratio below mu (``mu_spread``: its median
    over mu, logged; a stick-slipping piece sits far below) and the share of the late slide
    the blades gripped (``mu_grip``)."""
    noise, gap, lr = _mu_log_parts(mu, est, envelope, noise_share)
    return {"mu_plateau": float(est is not None), "mu_gap": gap,
            "mu_lr": lr, "sd_noise_mu": noise,
            "mu_spread": math.log(max(float(np.median(ratio)) / mu, 1e-6)), "mu_grip": grip}


def _mu_log_parts(mu: float, est: Any, envelope: float, noise_share: float = 0.0
                  ) -> tuple[float, float, float]:
    """On the log scale: the noise sd (the friction estimator's, and ``noise_share``, what
    sensor noise added to the envelope), the gap of mu to the force ratio's envelope and
    half the gap between the two half-spoons (0 where not defined)."""
    noise = lr = 0.0
    if est is not None:
        lo, hi = est.interval
        noise = (math.log(hi / lo) / (2 * 1.96)) if lo > 0 and hi > lo else 0.0
    noise = math.hypot(noise, noise_share)
    if est is not None and est.mu_left > 0 and est.mu_right > 0:
        lr = 0.5 * abs(math.log(est.mu_left / est.mu_right))
    gap = abs(math.log(envelope / mu)) if envelope > 0 else 0.0
    return noise, gap, lr


def _mu_sd_log(mu: float, est: Any, envelope: float, noise_share: float = 0.0) -> float:
    """Log-sd of mu: the noise (the friction estimator's interval, what sensor noise added
    to the envelope), and the disagreement of the plateau with the envelope and of the two
    half-spoons (see :func:`read_mu`)."""
    if est is None:  # the envelope alone: no check of it
        return math.hypot(abs(math.log(envelope / mu)) + 0.05, noise_share)
    return float(np.sqrt(np.sum(np.square(_mu_log_parts(mu, est, envelope, noise_share)))))


def _checked_inputs(t: Any, forces: Any, slide: Any, settle: Any, envelope: Any
                    ) -> tuple[np.ndarray, dict[str, np.ndarray], np.ndarray, np.ndarray | None]:
    """``(t, forces, slide, settle)`` checked (:func:`estimators.errors.check_traces`: finite
    1-D numbers, one a sample, time strictly increasing, at least 10 samples; the masks
    boolean arrays of one value a sample, ``settle`` possibly None), or the
    :class:`EstimationError` naming what is wrong; an unknown ``envelope`` too."""
    if not (isinstance(envelope, str) and envelope in SLIP_ENVELOPES):
        raise EstimationError(f"envelope must be one of {SLIP_ENVELOPES}, got {envelope!r:.40}")
    named = mapping("forces", forces)
    missing = [name for name in SLIP_FORCES if name not in named]
    if missing:
        raise EstimationError(f"forces must hold {', '.join(SLIP_FORCES)}; missing "
                              f"{', '.join(missing)}")
    tt, checked = check_traces(t, **{k: named[k] for k in SLIP_FORCES})
    masks: list[np.ndarray | None] = []
    for name, mask in (("slide", slide), ("settle", settle)):
        if mask is None and name == "settle":
            masks.append(None)
            continue
        if not (isinstance(mask, np.ndarray) and mask.dtype == bool and mask.shape == tt.shape):
            raise EstimationError(f"{name} must be a boolean array of one value per sample "
                                  f"{tt.shape}, got {type(mask).__name__} "
                                  f"{getattr(mask, 'dtype', '')} {getattr(mask, 'shape', '')}")
        masks.append(mask)
    return tt, checked, masks[0], masks[1]
