"""Slow environment checks: model-estimated observations against the oracle on held-back
seeds, and the check_env of the multi-row ids lives in test_env.py (marked slow).

Run: python -m pytest -q -m slow tests/test_env_slow.py
"""

from __future__ import annotations

import numpy as np
import pytest

from fetch_env.env import FoodFetchEnv

# Seeds never used by the fast tests or the benchmarks (those use < 3000).
HELD_BACK = range(90_000, 90_012)


def agreement(layout: str = "block", seeds=HELD_BACK, **kwargs) -> dict[str, np.ndarray]:
    """Relative error model/oracle - 1 per parameter over ``seeds`` (NaN where the model
    gave no estimate), plus the share of seeds with an estimate."""
    env = FoodFetchEnv(layout=layout, estimator="model", **kwargs)
    errs: dict[str, list[float]] = {k: [] for k in ("K1", "K2", "B", "mu", "g1", "tau1")}
    for seed in seeds:
        _, info = env.reset(seed=seed)
        for k in errs:
            est = info["estimated_params"][k]
            errs[k].append(np.nan if est is None else est / info["true_params"][k] - 1.0)
    return {k: np.array(v) for k, v in errs.items()}


@pytest.mark.slow
@pytest.mark.xfail(strict=True, reason=(
    "simulator physics (issue 2, geometry being changed): on the current traces the hold "
    "relaxes ~10x faster than the material's tau1 and the slip ratio sits ~2x above mu, so the "
    "model estimates are far from the oracle; remove this mark when the physics is fixed"))
def test_model_estimates_agree_with_the_oracle_on_held_back_seeds() -> None:
    errs = agreement()
    # Identified on most scenes, and then within what the estimators issue measured on
    # synthetic traces (2-3 %), with room for the short probe: g1, tau1, mu within 10 %.
    for k in ("g1", "tau1", "mu"):
        ok = np.isfinite(errs[k])
        assert ok.mean() >= 0.75, f"{k} identified on {ok.mean():.0%} of seeds"
        assert np.median(np.abs(errs[k][ok])) < 0.05, f"{k}: {errs[k]}"
        assert np.abs(errs[k][ok]).max() < 0.10, f"{k}: {errs[k]}"
    # K1, K2, B are compared with a nominal stiffness: a common factor is allowed, scatter
    # about it is not.
    for k in ("K1", "K2", "B"):
        ratio = 1.0 + errs[k][np.isfinite(errs[k])]
        assert np.std(np.log(ratio)) < 0.1, f"{k} ratios {ratio}"


if __name__ == "__main__":  # prints the figures quoted in the report
    for name, e in agreement().items():
        ok = np.isfinite(e)
        med = np.median(np.abs(e[ok])) if ok.any() else np.nan
        print(f"{name:5s} identified {ok.mean():4.0%}  median |model/oracle - 1| = {med:.3f}  "
              f"ratios {np.round(1 + e, 3)}")
