"""The -v2 environments: the -v1 rewards on scenes that leave room to choose the action.

FoodFetch-TwoRows-v1 draws one plate in five from the study's 0.0123 MPa level, whose packed
cubes the simulator does not resolve: their outcome changes with the time step and impratio,
so that fifth of the id's mean is a lottery no agent controls (docs/agents.md).
FoodFetch-TwoRows-v2 keeps v1's physics, probes, actions, observations and rewards and draws
its plates from the "resolved" scene space (``fetch_env.env_scenes.RESOLVED_TWO_ROWS_YOUNG``).

FoodFetch-Row-v1 is solved by one constant action: every row of its 8-14 mm cubes is held
and spared by the lightest touch.  FoodFetch-Row-v2 draws rows of any shape and of 8-22 mm
(the "any_shape" scene space, ``fetch_env.env_scenes.sample_any_shape_row``), whose best
angle follows the row, and observes them with the ``measure`` probes.
"""

from __future__ import annotations

from fetch_env.env import FoodFetchEnv, _docstring, _with_defaults

__all__ = ["FoodFetchRowV2Env", "FoodFetchTwoRowsV2Env"]


# Row-v2's arguments that differ from the v2 defaults (its docstring and __init__ share them)
_ROW_V2: dict[str, str] = {"scenes": "any_shape", "probes": "measure"}


class FoodFetchRowV2Env(FoodFetchEnv):
    __doc__ = _docstring(
        "FoodFetch-Row-v2: fetch a row of pieces of any shape, size and food.",
        "Two or three equal pieces (cube, ellipsoid or sphere; 8 to 22 mm, three only where "
        "they fit 44 mm) side by side across the clamp direction at one of the study's "
        "spacings, of one material from the food space; every piece held counts and every "
        "piece crushed costs its share.  The half-spoons close in a V about a hinge above "
        "the food: a cube is held by the lightest touch at its bottom edges, a round piece "
        "only nearer its equator, so a large sphere needs a deeper angle that crushes a small "
        "soft piece, and the angle must follow the row's shape and size.  The observations "
        "come from the ``measure`` probes (``probes=\"measure\"``).",
        "row", "v2", **_ROW_V2)

    __init__ = _with_defaults("row", "v2", **_ROW_V2)


class FoodFetchTwoRowsV2Env(FoodFetchEnv):
    __doc__ = _docstring(
        "FoodFetch-TwoRows-v2: fetch two rows of cubes, from very soft to hard.",
        "Two rows of cubes (8 to 12 mm), 1 mm apart along the clamp and 0.01 mm across, of "
        "one of five stiffness levels (0.06, 0.15, 5, 40 and 200 MPa) with viscoelasticity "
        "and friction from the food space.  As TwoRows-v1 with the study's 0.0123 MPa level, "
        "whose packed cubes the simulator does not resolve, replaced by 0.06 MPa, whose "
        "outcome at a light touch (0.04-0.05 rad) is the action's on 12-14 of 15 tuning "
        "plates (a deeper squeeze is still decided by the numerics on some).  Known "
        "limit: a light touch holds every plate and spares the soft ones, so 0.05 rad at the "
        "fastest clamp and lift is within 0.05 of the best angle on all 40 tuning scenes "
        "(0.925 against 0.928); what separates agents is speed and not squeezing deeper "
        "(docs/agents.md, 'How much choosing the angle is worth').",
        "two_rows", "v2")

    __init__ = _with_defaults("two_rows", "v2")
