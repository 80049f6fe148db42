"""What the probes return (:class:`ProbeOutcome`), and when it counts as reliable."""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

# A 95 % interval of g1, tau1 or mu wider than +-2.5 % makes an outcome unreliable.  With the
# calibration's error model giving the intervals (estimators.calibration.ErrorModel), this is
# about the widest that calls no tuning food reliable whose g1, tau1 or mu error exceeds 5 %:
# on the 256 tuning foods ("measure" probes, cross-validated) the narrowest such food's
# half-width was 2.2-5.0 % without noise, by how the folds fell (8-fold seed 0: 5.0 %; 4-fold
# seeds 1-3: 2.8, 3.5, 2.2 %; 8-fold seeds 1, 2: 2.6, 4.4 %), and 5.5-7.2 % with 1 % noise.
# The price: of the foods whose errors were all under 2 %, only about 3 of 77 (no noise) and
# none of 33 (1 % noise) have intervals that narrow (15 of 77 at 3.5 %).  What is left after
# the calibration is a per-food bias (the contact's compliance, the plate, the bulge) that
# the diagnostics predict only roughly, so an interval that must cover it cannot be narrow;
# a flag that never calls a 5 % miss reliable is then rarely True.  A calibration's error
# model may carry its own widths, chosen on its own tuning foods
# (estimators.calibration.ErrorModel.reliable_half_width; the "precise" probes', see
# benchmarks/validate_estimators.py RELIABILITY, which also limits the repeats' spread).
RELIABLE_HALF_WIDTH = 0.025


@dataclass
class ProbeOutcome:
    """What the probes measured: estimates (NaN where not identified) and diagnostics."""

    estimates: dict[str, float]
    visco_valid: bool
    friction_valid: bool
    wall_time: float
    piece_index: int
    warnings: list[str] = field(default_factory=list)
    traces: dict[str, dict[str, np.ndarray]] = field(default_factory=dict)
    details: dict[str, Any] = field(default_factory=dict)
    intervals: dict[str, tuple[float, float]] = field(default_factory=dict)

    @property
    def reliable(self) -> bool:
        """Both probes gave estimates, the 95 % intervals of g1, tau1 and mu are each
        within ``RELIABLE_HALF_WIDTH`` of the estimate, or the widths the calibration's
        error model was fitted with (``details["reliable_half_width"]``,
        :func:`apply_calibration`; with an error model the intervals include the per-food
        error it predicts), and the diagnostics that model limits
        (``details["reliable_diagnostics"]``, e.g. the repeated clamps' spread) are within
        their limits, and the food lies within the calibration's reference foods (no
        ``details["outside_reference"]``, :func:`apply_calibration`)."""
        if not (self.visco_valid and self.friction_valid) or self.details.get(
                "outside_reference"):
            return False
        widths = self.details.get("reliable_half_width") or {}
        for name in ("g1", "tau1", "mu"):
            if not within_half_width(self.estimates[name],
                                     self.intervals.get(name, (math.nan, math.nan)),
                                     widths.get(name, RELIABLE_HALF_WIDTH)):
                return False
        return not self.diagnostics_past_limits()

    def diagnostics_past_limits(self) -> list[str]:
        """The diagnostics past the limits of ``details["reliable_diagnostics"]``, as
        ``name=value``, or ``name missing`` where the probes gave none (which counts as
        past, as does a value that is not a finite number)."""
        values = self.details.get("diagnostics") or {}
        past = []
        for name, limit in (self.details.get("reliable_diagnostics") or {}).items():
            if name not in values:
                past.append(f"{name} missing")
                continue
            try:
                v = float(values[name])
            except (TypeError, ValueError):
                v = math.nan
            if not abs(v) <= limit:
                past.append(f"{name}={v:.3g}")
        return past


def within_half_width(value: float, interval: tuple[float, float],
                      half_width: float = RELIABLE_HALF_WIDTH) -> bool:
    """Whether ``interval`` is finite and lies within ``half_width`` (a share) of a positive
    ``value`` on both sides."""
    lo, hi = interval
    if not (math.isfinite(lo) and math.isfinite(hi) and value > 0):
        return False
    return max(hi / value - 1.0, 1.0 - lo / value) <= half_width


def _add_cpu(out: ProbeOutcome, key: str, start: float) -> None:
    """Add this process's CPU time since ``start`` to ``out.details[key]`` [s]: what the step
    costs a core, whatever else the machine runs (the wall time follows the load)."""
    out.details[key] = out.details.get(key, 0.0) + time.process_time() - start
