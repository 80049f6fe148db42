"""The -v1 environments: the -v0 physics with rewards and scenes that leave room to learn.

Each -v0 id is nearly solved by the study's one fixed action (Block 0.96 of a best 1.0),
because its scenes vary little and being slow costs nothing.  The -v1 ids keep the physics,
probes, actions and observations of -v0 and change what is asked (reasons in each class's
docstring, ``## Rewards`` and ``## Version history``): a time cost, damage charged per piece
by its share of the scene, and the wide scene space of ``fetch_env.env_scenes``.
"""

from __future__ import annotations

from fetch_env.env import FoodFetchEnv, _docstring, _with_defaults

__all__ = ["FoodFetchBlockV1Env", "FoodFetchDicedV1Env", "FoodFetchRowV1Env",
           "FoodFetchTwoRowsV1Env"]


class FoodFetchBlockV1Env(FoodFetchEnv):
    __doc__ = _docstring(
        "FoodFetch-Block-v1: fetch one food piece of any size, stiffness and friction.",
        "One piece (cube, ellipsoid or sphere) from the food space the estimators are "
        "validated on: 8 to 25 mm, very soft to firm (0.0123 to 5 MPa), slippery to grippy "
        "(mu 0.1 to 0.8).  A small piece is crushed by the angle that holds a large one, so "
        "the clamp angle must follow the piece's size; the time cost rewards the fastest "
        "clamp and lift that still hold.  Known limit: the stiffness and friction the probes "
        "measure change the best angle little here (an agent that sees only the sizes scores "
        "0.031 below search; docs/agents.md, 'How much choosing the angle is worth').",
        "block", "v1")

    __init__ = _with_defaults("block", "v1")


class FoodFetchRowV1Env(FoodFetchEnv):
    __doc__ = _docstring(
        "FoodFetch-Row-v1: fetch a single row of cubes of any food.",
        "Two or three cubes (8 to 14 mm) side by side across the clamp direction at one of "
        "the study's spacings, of one material from the food space; every cube held counts "
        "and every cube crushed costs its share.  Known limit: the lightest touch (0.03 rad, "
        "fastest) holds every row of this space, so one constant action is near the best "
        "on every scene (docs/agents.md, 'How much choosing the angle is worth').",
        "row", "v1")

    __init__ = _with_defaults("row", "v1")


class FoodFetchTwoRowsV1Env(FoodFetchEnv):
    __doc__ = _docstring(
        "FoodFetch-TwoRows-v1: fetch two rows of cubes of one of the study's stiffnesses.",
        "Two rows of cubes (8 to 12 mm), 1 mm apart along the clamp and 0.01 mm across, of "
        "one of the study's five stiffness levels (0.0123 to 200 MPa) with viscoelasticity "
        "and friction from the food space: soft rows are crushed by a firm clamp.  Known "
        "limit: 0.0123 MPa cubes packed this close are flung apart at squeezes of 5-15 % in "
        "a way that changes with the step, so one scene in five is a lottery for "
        "any agent (docs/agents.md, 'How much choosing the angle is worth'); "
        "FoodFetch-TwoRows-v2 leaves that level out.",
        "two_rows", "v1")

    __init__ = _with_defaults("two_rows", "v1")


class FoodFetchDicedV1Env(FoodFetchEnv):
    __doc__ = _docstring(
        "FoodFetch-Diced-v1: fetch a diced mix, charged piece by piece.",
        "Four to eight pieces (cube, ellipsoid, sphere; 7 to 12 mm) of the study's five "
        "stiffness levels packed on a jittered grid, with one friction coefficient per plate "
        "from 0.1 to 0.8.  Each crushed die costs its share of the plate, so fetching most "
        "pieces while sparing the softest is worth more than giving up.",
        "diced", "v1")

    __init__ = _with_defaults("diced", "v1")
