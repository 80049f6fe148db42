"""Calibration of a probe's systematic errors against foods of known parameters.

A clamp-and-hold probe does not see the food alone: the contact and the drive are compliant
in series with it (a stiff food's held moment relaxes more slowly than the food does,
``tau1 (1 + K2 / (K1 + k_c))``), friction at the faces holds part of the food's bulge, and
a round piece settles into the clamp.  These biases depend on the food and the probe, in
ways a single correction factor does not capture, but they are systematic: the same probe on
foods alike gives the same bias.  So, as an instrument is calibrated against reference
samples, a probe is calibrated against reference foods of known g1, tau1 and stiffness:

    log(estimate / truth) = b . x(food, estimate)

is fitted, by a robust least-squares fit (``scipy.optimize.least_squares``, soft L1 loss, so
that a few foods the probe failed on do not steer it), for the instantaneous stiffness
``K_el = K1 + K2``, for g1 and for tau1, with features ``x`` that the robot knows at the
time: the piece's shape and size (a camera), and the probe's own estimates of K_el, mu, g1
and tau1.  Applying it divides each estimate by ``exp(b . x)``; K1, K2 and B then follow
from the corrected K_el, g1 and tau1, so they stay one consistent SLS.

The simulator's probes ship calibrations fitted on the validation harness's tuning foods
(``fetch_env.probes``); a real robot's user fits their own from reference foods with
:func:`fit_calibration`.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

from estimators.errors import EstimationError

__all__ = ["FEATURES", "TARGETS", "Calibration", "features", "fit_calibration"]

FEATURES: tuple[str, ...] = ("1", "cube", "sphere", "log_size", "log_stiffness", "mu", "g1",
                             "log_tau1")
TARGETS: tuple[str, ...] = ("K_el", "g1", "tau1")
SHAPES = ("cube", "ellipsoid", "sphere")
_SIZE_REF = 0.015  # [m]
_STIFFNESS_REF = 1e6  # [N/m per m of size]


def features(shape: str, size: float, estimate: Mapping[str, float]) -> np.ndarray:
    """The feature vector ``x`` of one probed food (see :data:`FEATURES`).

    Args:
        shape: "cube", "ellipsoid" or "sphere". size: nominal size [m].
        estimate: the probe's K1, K2 [N/m], mu, g1, tau1 [s].

    Raises:
        EstimationError: an unknown shape, a size or estimate that is not finite and positive.
    """
    if shape not in SHAPES:
        raise EstimationError(f"shape must be one of {SHAPES}, got {shape!r}")
    values = {k: estimate.get(k, math.nan) for k in ("K1", "K2", "mu", "g1", "tau1")}
    for name, v in (("size", size), *values.items()):
        if not (isinstance(v, int | float | np.floating) and math.isfinite(v) and v > 0):
            raise EstimationError(f"calibration needs a finite, positive {name}, got {v!r}")
    k_el = values["K1"] + values["K2"]
    return np.array([1.0, shape == "cube", shape == "sphere", math.log(size / _SIZE_REF),
                     math.log(k_el / size / _STIFFNESS_REF), values["mu"], values["g1"],
                     math.log(values["tau1"])], dtype=float)


@dataclass(frozen=True)
class Calibration:
    """Coefficients ``b`` of ``log(estimate / truth) = b . x`` per target.

    Attributes:
        coefficients: target ("K_el", "g1", "tau1") -> one coefficient per :data:`FEATURES`.
        n_foods: foods it was fitted on. source: what it was fitted on (for the record).
    """

    coefficients: Mapping[str, Sequence[float]]
    n_foods: int = 0
    source: str = ""

    def __post_init__(self) -> None:
        for target in TARGETS:
            b = self.coefficients.get(target)
            if b is None or len(b) != len(FEATURES) or not all(math.isfinite(v) for v in b):
                raise EstimationError(
                    f"calibration coefficients for {target!r} must be {len(FEATURES)} finite "
                    f"numbers (for {FEATURES}), got {b!r}")

    def apply(self, shape: str, size: float, estimate: Mapping[str, float]
              ) -> tuple[dict[str, float], list[str]]:
        """The calibrated K1, K2, B, g1, tau1 (mu and any other keys unchanged), and warnings.

        A calibrated g1 that would reach 1 is held at 0.99 and said so.

        Raises:
            EstimationError: as :func:`features`.
        """
        x = features(shape, size, estimate)
        factor = {t: math.exp(float(np.dot(self.coefficients[t], x))) for t in TARGETS}
        k_el = (estimate["K1"] + estimate["K2"]) / factor["K_el"]
        g1 = estimate["g1"] / factor["g1"]
        warns = []
        if g1 >= 0.99:
            warns.append(f"calibrated g1 {g1:.4g} held at 0.99 (the model allows g1 < 1)")
            g1 = 0.99
        tau1 = estimate["tau1"] / factor["tau1"]
        out = dict(estimate)
        out.update(K1=(1 - g1) * k_el, K2=g1 * k_el, B=tau1 * g1 * k_el, g1=g1, tau1=tau1)
        return out, warns

    def to_dict(self) -> dict[str, object]:
        return {"features": list(FEATURES), "coefficients": {t: list(map(float, b)) for t, b in
                                                             self.coefficients.items()},
                "n_foods": self.n_foods, "source": self.source}

    @classmethod
    def from_dict(cls, data: Mapping[str, object]) -> Calibration:
        """Read :meth:`to_dict`'s form (refusing one made for other features)."""
        if list(data.get("features", [])) != list(FEATURES):  # type: ignore[call-overload]
            raise EstimationError(f"calibration features {data.get('features')!r} are not "
                                  f"{list(FEATURES)}")
        coef = data["coefficients"]
        if not isinstance(coef, Mapping):
            raise EstimationError(f"calibration coefficients must be a mapping, got {coef!r}")
        return cls({t: tuple(float(v) for v in coef[t]) for t in TARGETS},
                   int(data.get("n_foods", 0)), str(data.get("source", "")))  # type: ignore[arg-type]


def fit_calibration(foods: Sequence[tuple[str, float, Mapping[str, float], Mapping[str, float]]],
                    f_scale: float = 0.03, source: str = "") -> Calibration:
    """Fit a :class:`Calibration` on reference foods.

    Args:
        foods: ``(shape, size, estimate, truth)`` per food; estimate and truth give K1, K2,
            g1, tau1 (and the estimate mu).  Foods whose estimate is incomplete are skipped.
        f_scale: where the soft L1 loss turns from quadratic to linear, in log units (0.03:
            a 3 % miss counts fully, a 30 % miss a tenth as much as least squares would).
    Raises:
        EstimationError: fewer usable foods than twice the number of features.
    """
    rows, ys = [], {t: [] for t in TARGETS}
    for shape, size, est, true in foods:
        try:
            x = features(shape, size, est)
        except EstimationError:
            continue
        rows.append(x)
        ys["K_el"].append(math.log((est["K1"] + est["K2"]) / (true["K1"] + true["K2"])))
        ys["g1"].append(math.log(est["g1"] / true["g1"]))
        ys["tau1"].append(math.log(est["tau1"] / true["tau1"]))
    if len(rows) < 2 * len(FEATURES):
        raise EstimationError(f"calibration needs at least {2 * len(FEATURES)} foods with "
                              f"complete estimates, got {len(rows)}")
    X = np.array(rows)
    coef = {}
    for t in TARGETS:
        y = np.array(ys[t])
        fit = least_squares(lambda b, y=y: X @ b - y, np.zeros(X.shape[1]), loss="soft_l1",
                            f_scale=f_scale)
        coef[t] = tuple(float(v) for v in fit.x)
    return Calibration(coef, len(rows), source)
