"""The -v2 environments: the -v1 rewards on scenes the simulator resolves.

FoodFetch-TwoRows-v1 draws one plate in five from the study's 0.0123 MPa level, whose packed
cubes the simulator does not resolve: their outcome changes with the time step and impratio,
so that fifth of the id's mean is a lottery no agent controls (docs/agents.md).  The -v2 id
keeps v1's physics, probes, actions, observations and rewards and draws its plates from the
"resolved" scene space (``fetch_env.env_scenes.RESOLVED_TWO_ROWS_YOUNG``).
"""

from __future__ import annotations

from fetch_env.env import FoodFetchEnv, _docstring, _with_defaults

__all__ = ["FoodFetchTwoRowsV2Env"]


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
