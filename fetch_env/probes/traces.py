"""Reading a probe run's traces: the two half-spoons' mean moment, added sensor noise, and
the checks every fit makes of the run it is given."""

from __future__ import annotations

from typing import Any

import numpy as np

from fetch_env.controller import SimResult
from fetch_env.errors import require, require_finite, require_type


def _mean_moment(tr: dict[str, np.ndarray]) -> np.ndarray:
    return 0.5 * (tr["moment_left"] + tr["moment_right"])


def _noisy(x: np.ndarray, noise: float, rng: np.random.Generator | None) -> np.ndarray:
    """``x`` plus white noise of sd ``noise`` times its peak (a sensor's noise floor)."""
    if noise <= 0 or rng is None:
        return x
    return x + noise * float(np.max(np.abs(x))) * rng.standard_normal(x.shape)


def _check_run_args(result: Any, experiment: str, noise: Any, rng: Any) -> None:
    """Refuse a run that is not a ``SimResult`` of ``experiment``, a noise outside [0, 0.5]
    and an ``rng`` that is not a numpy Generator or None."""
    require_type("result", result, SimResult, f"a SimResult of the {experiment} experiment")
    require(result.experiment == experiment, "result", result.experiment,
            f"a run of the {experiment} experiment")
    require_finite("noise", noise)
    require(0.0 <= noise <= 0.5, "noise", noise, "in [0, 0.5]")
    require_type("rng", rng, np.random.Generator | None, "a numpy.random.Generator or None")
