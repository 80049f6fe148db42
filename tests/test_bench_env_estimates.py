"""``benchmarks/bench_env_estimates.py``'s count of the env's reliable flag against the
errors: which scenes are misses, which are good, and how the flag fared on each."""

from __future__ import annotations

import math

from benchmarks.bench_env_estimates import reliable_counts


def test_reliable_counts_misses_and_good_scenes() -> None:
    # scene 0: good (all under 2 %), flagged; 1: a 6 % tau1 miss called reliable; 2: a miss
    # (g1 not identified counts as one), unreliable; 3: between the bars, in neither count
    run = {"errors": {"g1": [0.01, 0.0, math.nan, 0.03], "tau1": [-0.015, 0.06, 0.0, 0.0],
                      "mu": [0.0, 0.0, 0.0, -0.01]},
           "reliable": [False, True, False, True]}
    assert reliable_counts(run) == "1 of 2 / 1 of 1"
    assert reliable_counts({"errors": run["errors"]}) == "-"  # a run recorded without it
