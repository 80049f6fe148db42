"""The -v3 environments: the -v2 rewards on scenes whose best action follows the scene.

FoodFetch-TwoRows-v2 is solved by one constant action: its plates of 8-12 mm cubes are all
held by a light touch at the cubes' bottom edges, and 0.05 rad at the fastest clamp and lift
is within 0.05 of the best angle on every tuning plate.  FoodFetch-TwoRows-v3 draws two-row
plates of any shape and of 8-20 mm (the "any_shape_two_rows" scene space,
``fetch_env.env_scenes.sample_any_shape_two_rows``) and observes them with the ``measure``
probes, as FoodFetch-Row-v2 does for one row.
"""

from __future__ import annotations

from fetch_env.env import FoodFetchEnv, _docstring, _with_defaults

__all__ = ["FoodFetchTwoRowsV3Env"]


# TwoRows-v3's arguments that differ from the v2 defaults (its docstring and __init__ share them)
_TWO_ROWS_V3: dict[str, str] = {"scenes": "any_shape_two_rows", "probes": "measure"}


class FoodFetchTwoRowsV3Env(FoodFetchEnv):
    __doc__ = _docstring(
        "FoodFetch-TwoRows-v3: fetch two rows of pieces of any shape and size.",
        "Two rows along the clamp, 1 mm apart, of two or three equal pieces each (cube, "
        "ellipsoid or sphere; 8 to 20 mm, three to a row only where they fit 44 mm; 0.01 mm "
        "apart across), of one of the resolved space's five stiffness levels (0.06, 0.15, 5, "
        "40 and 200 MPa) with viscoelasticity and friction from the food space.  The "
        "half-spoons squeeze the two rows in series: cubes are held at their bottom edges by "
        "a light touch, round pieces only nearer their equators, so the angle must follow the "
        "plate's shape and size.  The observations come from the ``measure`` probes "
        "(``probes=\"measure\"``).",
        "two_rows", "v2", **_TWO_ROWS_V3)

    __init__ = _with_defaults("two_rows", "v2", **_TWO_ROWS_V3)
