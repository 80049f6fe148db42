"""The shipped calibrations of the presets' probes (:data:`PROBE_CALIBRATIONS`), which one an
environment applies (:func:`calibration_for`), and how a calibration corrects an outcome and
sets its intervals (:func:`apply_calibration`)."""

from __future__ import annotations

import json
import math
import os
from pathlib import Path

from estimators import EstimationError
from estimators.calibration import ERROR_TARGETS, Calibration
from estimators.uncertainty import DRIFT_DIAGNOSTICS, MAX_LOG_HALF_WIDTH
from fetch_env.errors import require_type
from fetch_env.probes.config import PARAM_NAMES
from fetch_env.probes.results import ProbeOutcome
from fetch_env.spaces import VISCO_NAMES


def apply_calibration(shape: str, size: float, calibration: Calibration,
                      out: ProbeOutcome) -> None:
    """Apply ``calibration`` to complete estimates of a piece of ``shape`` and ``size``.

    The intervals of K1, K2, B move with the estimates.  Where the calibration has an error
    model (:class:`estimators.calibration.ErrorModel`), the 95 % intervals of g1, tau1 and
    mu are its ``exp(+-half_width)`` around the calibrated estimate, from the probes'
    diagnostics in ``out.details["diagnostics"]`` (NaN where one is missing),
    ``details["error_half_width"]`` keeps the half-widths, and
    ``details["reliable_half_width"]`` and ``details["reliable_diagnostics"]`` the model's
    own widths and diagnostic limits for :attr:`ProbeOutcome.reliable`, where it has them
    (a warning names the diagnostics past their limits).  A food outside the calibration's
    reference foods on either side, in size, K1 + K2 over size, mu, g1 or tau1
    (:meth:`estimators.calibration.Calibration.outside_reference`), is extrapolated to:
    ``details["outside_reference"]`` says how, a warning says so, and the outcome is not
    reliable; its estimates and intervals are still given.  Where the model has a noisy model
    and the food's traces carry sensor noise (:func:`estimators.calibration.noisy_traces`),
    that one gives the widths and the limits.
    """
    require_type("calibration", calibration, Calibration, "a Calibration")
    require_type("out", out, ProbeOutcome, "a ProbeOutcome")
    est = out.estimates
    if not (out.visco_valid and out.friction_valid
            and all(math.isfinite(est[k]) and est[k] > 0 for k in PARAM_NAMES)):
        out.warnings.append("not calibrated: the estimates are incomplete")
        return
    own = dict(est)
    _flag_outside_reference(shape, size, calibration, own, out)
    try:
        fixed, warns = calibration.apply(shape, size, own, out.details.get("diagnostics", {}))
    except EstimationError as exc:
        out.warnings.append(f"not calibrated: {exc}")
        if calibration.error_model is not None:  # its intervals are for calibrated values
            for k in _modelled_intervals(calibration.error_model.targets):
                out.intervals[k] = (math.nan, math.nan)
                out.warnings.append(f"no {k} interval: the estimates are not calibrated")
        return
    for k in VISCO_NAMES:
        ratio = fixed[k] / est[k]
        lo, hi = out.intervals.get(k, (math.nan, math.nan))
        out.intervals[k] = (lo * ratio, hi * ratio)
    out.details["uncalibrated"] = own
    out.details["calibration"] = calibration.source
    est.update(fixed)
    out.warnings += warns
    if calibration.error_model is None:
        return
    # the model for this food: the noisy one where its traces carry sensor noise
    model = calibration.error_model.for_food(out.details.get("diagnostics", {}))
    widths = {}
    for k in model.targets:
        try:
            widths[k] = model.half_width(k, shape, size, own, out.details.get("diagnostics", {}))
        except EstimationError as exc:
            widths[k] = math.nan
            out.warnings.append(f"no {k} interval: {exc}")
    for k, width in _interval_half_widths(widths, est["g1"]).items():
        out.intervals[k] = _log_width_interval(est[k], width)
    out.details["error_half_width"] = widths
    if model.reliable_half_width:
        out.details["reliable_half_width"] = dict(model.reliable_half_width)
    if model.reliable_diagnostics:
        out.details["reliable_diagnostics"] = dict(model.reliable_diagnostics)
        past = out.diagnostics_past_limits()
        if past:
            out.warnings.append("not reliable: the probes did not measure this food "
                                f"reproducibly ({', '.join(past)}, past the error model's "
                                "limits)")


def _flag_outside_reference(shape: str, size: float, calibration: Calibration,
                            own: dict[str, float], out: ProbeOutcome) -> None:
    """Where the probed food (``own``: its uncalibrated estimates) lies outside the
    calibration's reference foods, say how in ``out.details["outside_reference"]`` and a
    warning (:attr:`ProbeOutcome.reliable` is then False), whether or not the calibration
    then applies."""
    try:
        outside = calibration.outside_reference(shape, size, own)
    except EstimationError:  # an estimate the calibration cannot read: apply() says why
        return
    if outside:
        out.details["outside_reference"] = outside
        out.warnings.append("not reliable: this food lies outside the calibration's "
                            f"reference foods, so its correction and intervals are "
                            f"extrapolated: {'; '.join(outside)}")


_VISCO_SPRINGS = ("K1", "K2", "B")


def _modelled_intervals(targets: tuple[str, ...]) -> tuple[str, ...]:
    """The parameters whose intervals an error model with ``targets`` gives."""
    return (*ERROR_TARGETS, *(_VISCO_SPRINGS if "K_el" in targets else ()))


def _interval_half_widths(widths: dict[str, float], g1: float) -> dict[str, float]:
    """Log half-widths by parameter from an error model's (by target): g1, tau1 and mu its
    own; where it has K_el, K1 = (1 - g1) K_el, K2 = g1 K_el and B = tau1 K2 add their
    parts in quadrature (log(1 - g1) moves g1 / (1 - g1) times as much as log g1)."""
    out = {k: widths[k] for k in ERROR_TARGETS}
    if "K_el" in widths:
        w_k, w_g, w_t = widths["K_el"], widths["g1"], widths["tau1"]
        out["K1"] = math.hypot(w_k, g1 / (1.0 - g1) * w_g)
        out["K2"] = math.hypot(w_k, w_g)
        out["B"] = math.sqrt(w_k**2 + w_g**2 + w_t**2)
    return out


def _log_width_interval(value: float, half_width: float) -> tuple[float, float]:
    """``value * exp(+-half_width)``; (0, inf) where the half-width is too wide for a float
    (an error model fitted on a user's own foods can predict one), NaN where it is NaN."""
    if half_width > MAX_LOG_HALF_WIDTH:
        return 0.0, math.inf
    return value * math.exp(-half_width), value * math.exp(half_width)


def reads_drift(calibration: Calibration | None) -> bool:
    """Whether the probes must compute the drift diagnostics, which cost a fit: where the
    calibration reads them (as features, or in its error model's reliability limits), or
    where none is applied (a run that a calibration may be fitted on)."""
    if calibration is None:
        return True
    read = set(calibration.feature_names)
    model = calibration.error_model
    for m in (model, model and model.noisy):
        if m is not None:
            read |= set(m.reliable_diagnostics)
    return not read.isdisjoint(DRIFT_DIAGNOSTICS)


CALIBRATION_FILE = Path(__file__).parents[1] / "assets" / "probe_calibration.json"


def load_calibrations(path: Path = CALIBRATION_FILE) -> dict[str, Calibration]:
    """The shipped calibrations by preset name (none where the file is absent)."""
    require_type("path", path, str | os.PathLike, "a file name")
    path = Path(path)
    if not path.exists():
        return {}
    data = json.loads(path.read_text())
    return {name: Calibration.from_dict(entry) for name, entry in data.items()}


PROBE_CALIBRATIONS: dict[str, Calibration] = load_calibrations()


def scene_calibration_key(preset: str, layout: str, scenes: str) -> str:
    """The key of ``preset``'s calibration fitted on the pieces of ``layout``'s scenes in the
    scene space ``scenes`` (in :data:`PROBE_CALIBRATIONS` where one is shipped)."""
    return f"{preset}/{layout}-{scenes}"


def calibration_for(preset: str, layout: str | None = None,
                    scenes: str | None = None) -> Calibration | None:
    """The shipped calibration of ``preset``'s probes for an environment's observations.

    Where one was fitted on the pieces of ``layout``'s scenes in ``scenes`` (the Block
    scenes of the study space, whose foods span a narrower range than the food space: 10-20
    mm, g1 0.2-0.6, tau1 1-6 s, mu 0.15-0.6), that one: an instrument is calibrated against
    reference samples like those it will measure, and a log-linear correction fitted on
    them fits them better than one fitted over the whole food space (on 256 Block scenes of
    seed 95000, 8-fold cross-validated, the ``measure`` probes' tau1 median |error| 1.3 %
    against the food-space calibration's 1.7 %; docs/estimator_validation.md).  Else the
    preset's food-space calibration; None for a preset without one.
    """
    if layout is not None and scenes is not None:
        own = PROBE_CALIBRATIONS.get(scene_calibration_key(preset, layout, scenes))
        if own is not None:
            return own
    return PROBE_CALIBRATIONS.get(preset)
