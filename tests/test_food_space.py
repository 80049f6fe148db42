"""The food space: one documented set of ranges, space-filling designs, disjoint seeds."""

from __future__ import annotations

import numpy as np
import pytest

from fetch_env.errors import InvalidParameterError
from fetch_env.food_space import (
    RANGES,
    REPORTING_SEED,
    STIFF_YOUNG_RANGE,
    TUNING_SEED,
    corner_foods,
    sample_foods,
)
from fetch_env.layouts import SHAPES, Piece


def test_design_is_reproducible_and_seeds_differ() -> None:
    a = sample_foods(16, TUNING_SEED)
    assert a == sample_foods(16, TUNING_SEED)
    b = sample_foods(16, REPORTING_SEED)
    assert not {(f.size, f.young) for f in a} & {(f.size, f.young) for f in b}


@pytest.mark.parametrize("seed", [TUNING_SEED, REPORTING_SEED])
def test_design_fills_every_range(seed: int) -> None:
    """64 foods put at least 3 in every fifth of every range (log-scaled where documented),
    and at least 16 of every shape: a space-filling design, not a cluster."""
    foods = sample_foods(64, seed)
    for name, (lo, hi, log) in RANGES.items():
        v = np.array([getattr(f, name) for f in foods])
        assert v.min() >= lo and v.max() <= hi, name
        u = (np.log(v / lo) / np.log(hi / lo)) if log else (v - lo) / (hi - lo)
        counts = np.histogram(u, bins=5, range=(0, 1))[0]
        assert counts.min() >= 3, (name, counts)
    for shape in SHAPES:
        assert sum(f.shape == shape for f in foods) >= 16


def test_foods_build_pieces_and_the_stiff_extension_is_flagged() -> None:
    for f in sample_foods(8, TUNING_SEED):
        assert isinstance(f.piece(), Piece)
        assert not f.stiff
    stiff = sample_foods(8, REPORTING_SEED, young_range=STIFF_YOUNG_RANGE)
    assert all(f.stiff and STIFF_YOUNG_RANGE[0] <= f.young <= STIFF_YOUNG_RANGE[1]
               for f in stiff)


def test_corners_cover_every_shape_size_and_stiffness() -> None:
    corners = corner_foods()
    assert len(corners) == 24
    keys = {(f.shape, f.size, f.young) for f in corners}
    assert len(keys) == 12
    for f in corners:
        f.piece()  # every corner is a valid piece


@pytest.mark.parametrize("kwargs", [
    {"n": 0, "seed": 1}, {"n": 5000, "seed": 1}, {"n": 2.5, "seed": 1}, {"n": 4, "seed": -1},
    {"n": 4, "seed": 1, "young_range": (5e6, 1e6)}, {"n": 4, "seed": 1, "young_range": (0, 1)},
])
def test_bad_design_arguments_name_the_value(kwargs: dict) -> None:
    with pytest.raises(InvalidParameterError):
        sample_foods(**kwargs)
