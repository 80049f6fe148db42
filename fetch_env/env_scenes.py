"""Scenes for the Gymnasium environments: what each id samples at reset, and named presets.

Every random choice is drawn from the generator passed in (the env's ``np_random``), so a seed
fixes the scene.  The ranges are module constants so that the environment docstrings, the
tests and the agents read the same numbers.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Mapping
from typing import Any

import numpy as np

from fetch_env import food_space
from fetch_env.errors import (
    InvalidParameterError,
    require,
    require_int,
    require_pieces,
    require_type,
)
from fetch_env.layouts import SHAPES, Piece, diced_mix, grid, single_block, single_row, two_rows
from fetch_env.materials import PRESETS, STUDY_LEVELS, Material

LAYOUTS: tuple[str, ...] = ("block", "row", "two_rows", "diced")

# Material ranges sampled for Block and Row scenes (one material per scene).  Young's modulus
# is log-uniform over the soft-to-firm foods the study calls food-like (agar, radish, carrot,
# gummy candy); 200 MPa "hard" pieces appear in TwoRows and Diced, as in the study.
YOUNG_RANGE = (0.05e6, 5e6)  # [Pa], log-uniform
POISSON_RANGE = (0.25, 0.45)  # [-]
DENSITY_RANGE = (950.0, 1150.0)  # [kg/m^3]
G1_RANGE = (0.2, 0.6)  # [-]
TAU1_RANGE = (1.0, 6.0)  # [s], log-uniform
MU_RANGE = (0.15, 0.6)  # [-] half-spoon/food friction
PLATE_MU = 0.1  # [-] the study keeps the plate slippery

BLOCK_SIZE_RANGE = (0.010, 0.020)  # [m] nominal size of the single piece
ROW_N_RANGE = (2, 3)  # pieces in the row, inclusive
ROW_SIZE_RANGE = (0.010, 0.013)  # [m] cube edge
ROW_SPACINGS = (0.001, 0.0005, 0.0003, 0.0001)  # [m] across the clamp: the study's four
TWO_ROWS_N_RANGE = (2, 3)  # pieces per row, inclusive
TWO_ROWS_SIZE_RANGE = (0.010, 0.012)  # [m]
TWO_ROWS_SPACING_ALONG = 0.001  # [m] the study's
TWO_ROWS_SPACING_ACROSS = 0.00001  # [m] the study's 0.01 mm
TWO_ROWS_MATERIALS = ("hard-200MPa", "soft-0.2MPa")  # drawn with equal chance
DICED_N_RANGE = (4, 8)  # pieces, inclusive; kept small so an episode stays near one second
DICED_SIZE_RANGE = (0.007, 0.010)  # [m]

SAMPLING: dict[str, dict[str, Any]] = {
    "block": {"shape": SHAPES, "size_m": BLOCK_SIZE_RANGE, "young_pa": YOUNG_RANGE,
              "poisson": POISSON_RANGE, "density": DENSITY_RANGE, "g1": G1_RANGE,
              "tau1_s": TAU1_RANGE, "mu": MU_RANGE},
    "row": {"n": ROW_N_RANGE, "size_m": ROW_SIZE_RANGE, "spacing_across_m": ROW_SPACINGS,
            "material": "as block"},
    "two_rows": {"n_per_row": TWO_ROWS_N_RANGE, "size_m": TWO_ROWS_SIZE_RANGE,
                 "spacing_along_m": TWO_ROWS_SPACING_ALONG,
                 "spacing_across_m": TWO_ROWS_SPACING_ACROSS, "material": TWO_ROWS_MATERIALS},
    "diced": {"n": DICED_N_RANGE, "size_m": DICED_SIZE_RANGE, "material": STUDY_LEVELS,
              "shape": SHAPES},
}

# The "wide" scene space of the -v1 ids: the food space the estimators are validated on
# (fetch_env.food_space: 8-25 mm, 0.0123-5 MPa, g1 0.1-0.8, tau1 0.5-10 s, mu 0.1-0.8), so
# that slippery, very soft, stiff, small and large pieces all occur and no single fixed
# action is near the best on every scene (the study's scenes vary only the layout).
SCENE_SPACES: tuple[str, ...] = ("study", "wide", "resolved", "any_shape",
                                 "any_shape_two_rows")
WIDE_ROW_SIZE_RANGE = (0.008, 0.014)  # [m] three 14 mm cubes still fit the 48 mm blades
WIDE_TWO_ROWS_SIZE_RANGE = (0.008, 0.012)  # [m]
WIDE_DICED_SIZE_RANGE = (0.007, 0.012)  # [m]
# The "resolved" scene space (the -v2 ids): the wide space without the scenes the simulator
# does not resolve.  0.0123 MPa cubes packed in a two-row grid (0.01 mm apart across) are
# flung apart by squeezes of a few per cent in a way that changes with the time step and
# impratio (docs/agents.md, "Very soft two-row plates are outside what the simulator
# resolves"), so a two-row plate's softest level is 0.06 MPa: at the light touch that holds
# it (0.04 and 0.05 rad) its outcome agrees across the step and impratio on 14 and 12 of 15
# tuning plates, 0.0123 MPa's on 7 and 4 (benchmarks/very_soft_plates.py --levels).  Every
# other layout is drawn as in the wide space.
RESOLVED_TWO_ROWS_YOUNG: tuple[float, ...] = (200e6, 40e6, 5e6, 0.15e6, 0.06e6)  # [Pa]

# The "any_shape" scene space (FoodFetch-Row-v2): the resolved space with rows of any shape and
# of the food space's sizes that fit the blades.  Rows of 8-14 mm cubes (Row-v1) are all
# held and spared by the lightest touch (0.03 rad), because the half-spoons' V holds a cube
# pressed at its bottom edges; a round piece is touched only nearer its equator, so a large
# sphere or ellipsoid needs a deeper angle (on the 40 tuning rows, 0.04 rad left five of
# 16-21 mm on the plate) that crushes the smallest soft cubes (0.05 rad, two of 8.6-8.8 mm;
# docs/agents.md, "How much choosing the angle is worth").  Three pieces are drawn only
# where three fit ANY_SHAPE_ROW_WIDTH; two 22 mm pieces span at most 45 mm of the 48 mm
# blades.
ANY_SHAPE_ROW_SIZE_RANGE = (0.008, 0.022)  # [m]
ANY_SHAPE_ROW_WIDTH = 0.044  # [m] widest row of three: 2 mm of blade left each side

WIDE_SAMPLING: dict[str, dict[str, Any]] = {
    "block": {"shape": SHAPES, "size_m": food_space.SIZE_RANGE,
              "young_pa": food_space.YOUNG_RANGE, "poisson": POISSON_RANGE,
              "density": DENSITY_RANGE, "g1": food_space.G1_RANGE,
              "tau1_s": food_space.TAU1_RANGE, "mu": food_space.MU_RANGE},
    "row": {"n": ROW_N_RANGE, "size_m": WIDE_ROW_SIZE_RANGE,
            "spacing_across_m": ROW_SPACINGS, "material": "as block"},
    "two_rows": {"n_per_row": TWO_ROWS_N_RANGE, "size_m": WIDE_TWO_ROWS_SIZE_RANGE,
                 "spacing_along_m": TWO_ROWS_SPACING_ALONG,
                 "spacing_across_m": TWO_ROWS_SPACING_ACROSS,
                 "young_pa": STUDY_LEVELS, "g1, tau1_s, mu": "as block"},
    "diced": {"n": DICED_N_RANGE, "size_m": WIDE_DICED_SIZE_RANGE, "material": STUDY_LEVELS,
              "shape": SHAPES, "mu": "one per scene, as block"},
}
RESOLVED_SAMPLING: dict[str, dict[str, Any]] = {
    **WIDE_SAMPLING,
    "two_rows": {**WIDE_SAMPLING["two_rows"], "young_pa": RESOLVED_TWO_ROWS_YOUNG},
}
ANY_SHAPE_SAMPLING: dict[str, dict[str, Any]] = {
    **RESOLVED_SAMPLING,
    "row": {"shape": SHAPES, "size_m": ANY_SHAPE_ROW_SIZE_RANGE,
            "spacing_across_m": ROW_SPACINGS,
            "n": f"2 or 3, 3 only where the row fits {ANY_SHAPE_ROW_WIDTH * 1000:g} mm",
            "material": "as block"},
}
# The "any_shape_two_rows" scene space (FoodFetch-TwoRows-v3): the any_shape space with
# two-row plates of any shape.  Two rows of 8-12 mm cubes (TwoRows-v2) are all held by a
# light touch at the cubes' bottom edges, one constant action; two rows of round pieces are
# touched nearer their equators, through two pieces in series, so the angle must follow the
# plate's shape and size.  The stiffness levels stay the resolved space's.
ANY_SHAPE_TWO_ROWS_SIZE_RANGE = (0.008, 0.020)  # [m] two 20 mm rows span 41 mm along the clamp
ANY_SHAPE_TWO_ROWS_SAMPLING: dict[str, dict[str, Any]] = {
    **ANY_SHAPE_SAMPLING,
    "two_rows": {"shape": SHAPES, "size_m": ANY_SHAPE_TWO_ROWS_SIZE_RANGE,
                 "n_per_row": f"2 or 3, 3 only where a row fits {ANY_SHAPE_ROW_WIDTH * 1000:g} mm",
                 "spacing_along_m": TWO_ROWS_SPACING_ALONG,
                 "spacing_across_m": TWO_ROWS_SPACING_ACROSS,
                 "young_pa": RESOLVED_TWO_ROWS_YOUNG, "g1, tau1_s, mu": "as block"},
}


def _log_uniform(rng: np.random.Generator, lo: float, hi: float) -> float:
    return float(math.exp(rng.uniform(math.log(lo), math.log(hi))))


def sample_material(rng: np.random.Generator) -> Material:
    """One food material from the documented ranges (Block and Row scenes)."""
    return Material(young=_log_uniform(rng, *YOUNG_RANGE),
                    poisson=float(rng.uniform(*POISSON_RANGE)),
                    density=float(rng.uniform(*DENSITY_RANGE)),
                    g1=float(rng.uniform(*G1_RANGE)),
                    tau1=_log_uniform(rng, *TAU1_RANGE),
                    mu=float(rng.uniform(*MU_RANGE)), plate_mu=PLATE_MU, name="sampled")


def sample_wide_material(rng: np.random.Generator, young: float | None = None) -> Material:
    """One food material of the wide scene space (``young`` fixed if given)."""
    return Material(
        young=_log_uniform(rng, *food_space.YOUNG_RANGE) if young is None else young,
        poisson=float(rng.uniform(*POISSON_RANGE)), density=float(rng.uniform(*DENSITY_RANGE)),
        g1=float(rng.uniform(*food_space.G1_RANGE)), tau1=_log_uniform(rng, *food_space.TAU1_RANGE),
        mu=float(rng.uniform(*food_space.MU_RANGE)), plate_mu=PLATE_MU, name="sampled")


def _pieces_in_row(rng: np.random.Generator, size: float, spacing: float) -> int:
    """Two or three pieces across the clamp, three only where they fit
    ``ANY_SHAPE_ROW_WIDTH`` (every shape's extent across the clamp is its size)."""
    n_max = 3 if 3 * size + 2 * spacing <= ANY_SHAPE_ROW_WIDTH else 2
    return int(rng.integers(2, n_max + 1))


def sample_any_shape_row(rng: np.random.Generator) -> tuple[Piece, ...]:
    """A row of the "any_shape" space (:data:`ANY_SHAPE_SAMPLING`): two or three equal pieces
    of one shape and material side by side across the clamp direction."""
    shape = str(rng.choice(SHAPES))
    size = float(rng.uniform(*ANY_SHAPE_ROW_SIZE_RANGE))
    spacing = float(rng.choice(ROW_SPACINGS))
    n = _pieces_in_row(rng, size, spacing)
    return grid(1, n, size, 0.001, spacing, sample_wide_material(rng),
                shape=shape)  # type: ignore[arg-type]


def sample_any_shape_two_rows(rng: np.random.Generator) -> tuple[Piece, ...]:
    """A plate of the "any_shape_two_rows" space (:data:`ANY_SHAPE_TWO_ROWS_SAMPLING`): two
    rows along the clamp of two or three equal pieces of one shape and material each."""
    shape = str(rng.choice(SHAPES))
    size = float(rng.uniform(*ANY_SHAPE_TWO_ROWS_SIZE_RANGE))
    n = _pieces_in_row(rng, size, TWO_ROWS_SPACING_ACROSS)
    young = float(rng.choice(RESOLVED_TWO_ROWS_YOUNG))
    return grid(2, n, size, TWO_ROWS_SPACING_ALONG, TWO_ROWS_SPACING_ACROSS,
                sample_wide_material(rng, young), shape=shape)  # type: ignore[arg-type]


def sample_wide_scene(layout: str, rng: np.random.Generator,
                      two_rows_young: tuple[float, ...] | None = None,
                      any_shape_rows: bool = False) -> tuple[Piece, ...]:
    """Draw a scene of ``layout`` from the wide space (:data:`WIDE_SAMPLING`) with ``rng``;
    ``two_rows_young`` [Pa] replaces the study's five levels of a two-row plate (the
    "resolved" space's :data:`RESOLVED_TWO_ROWS_YOUNG`), ``any_shape_rows`` draws a row
    with :func:`sample_any_shape_row` (the "any_shape" space)."""
    if layout == "row" and any_shape_rows:
        return sample_any_shape_row(rng)
    if layout == "block":
        shape = str(rng.choice(SHAPES))
        size = float(rng.uniform(*food_space.SIZE_RANGE))
        return (Piece(shape, size, sample_wide_material(rng)),)  # type: ignore[arg-type]
    if layout == "row":
        n = int(rng.integers(ROW_N_RANGE[0], ROW_N_RANGE[1] + 1))
        size = float(rng.uniform(*WIDE_ROW_SIZE_RANGE))
        spacing = float(rng.choice(ROW_SPACINGS))
        return single_row(spacing_across=spacing, n=n, size=size,
                          material=sample_wide_material(rng))
    if layout == "two_rows":
        n = int(rng.integers(TWO_ROWS_N_RANGE[0], TWO_ROWS_N_RANGE[1] + 1))
        size = float(rng.uniform(*WIDE_TWO_ROWS_SIZE_RANGE))
        if two_rows_young is None:
            young = PRESETS[str(rng.choice(STUDY_LEVELS))].young
        else:
            young = float(rng.choice(two_rows_young))
        return two_rows(material=sample_wide_material(rng, young), n=n, size=size,
                        spacing_along=TWO_ROWS_SPACING_ALONG,
                        spacing_across=TWO_ROWS_SPACING_ACROSS)
    if layout == "diced":
        n = int(rng.integers(DICED_N_RANGE[0], DICED_N_RANGE[1] + 1))
        pieces = diced_mix(rng, n_pieces=n, size_range=WIDE_DICED_SIZE_RANGE)
        mu = float(rng.uniform(*food_space.MU_RANGE))
        return tuple(dataclasses.replace(p, material=dataclasses.replace(p.material, mu=mu))
                     for p in pieces)
    raise InvalidParameterError(f"layout must be one of {LAYOUTS}, got {layout!r}")


def sample_scene(layout: str, rng: np.random.Generator,
                 scenes: str = "study") -> tuple[Piece, ...]:
    """Draw a scene of ``layout`` from the documented ranges of ``scenes`` (the -v0 ids'
    "study" space, the -v1 ids' "wide" one, TwoRows-v2's "resolved" one, Row-v2's
    "any_shape" one or TwoRows-v3's "any_shape_two_rows" one), using only ``rng``."""
    require(isinstance(layout, str) and layout in LAYOUTS, "layout", layout, f"one of {LAYOUTS}")
    require_type("rng", rng, np.random.Generator, "a numpy.random.Generator")
    require(isinstance(scenes, str) and scenes in SCENE_SPACES, "scenes", scenes,
            f"one of {SCENE_SPACES}")
    if scenes == "wide":
        return sample_wide_scene(layout, rng)
    if scenes == "any_shape_two_rows" and layout == "two_rows":
        return sample_any_shape_two_rows(rng)
    if scenes in ("resolved", "any_shape", "any_shape_two_rows"):
        return sample_wide_scene(layout, rng, RESOLVED_TWO_ROWS_YOUNG,
                                 any_shape_rows=scenes != "resolved")
    if scenes != "study":
        raise InvalidParameterError(f"scenes must be one of {SCENE_SPACES}, got {scenes!r}")
    if layout == "block":
        shape = str(rng.choice(SHAPES))
        size = float(rng.uniform(*BLOCK_SIZE_RANGE))
        return (Piece(shape, size, sample_material(rng)),)  # type: ignore[arg-type]
    if layout == "row":
        n = int(rng.integers(ROW_N_RANGE[0], ROW_N_RANGE[1] + 1))
        size = float(rng.uniform(*ROW_SIZE_RANGE))
        spacing = float(rng.choice(ROW_SPACINGS))
        return single_row(spacing_across=spacing, n=n, size=size, material=sample_material(rng))
    if layout == "two_rows":
        n = int(rng.integers(TWO_ROWS_N_RANGE[0], TWO_ROWS_N_RANGE[1] + 1))
        size = float(rng.uniform(*TWO_ROWS_SIZE_RANGE))
        mat = PRESETS[str(rng.choice(TWO_ROWS_MATERIALS))]
        return two_rows(material=mat, n=n, size=size, spacing_along=TWO_ROWS_SPACING_ALONG,
                        spacing_across=TWO_ROWS_SPACING_ACROSS)
    if layout == "diced":
        n = int(rng.integers(DICED_N_RANGE[0], DICED_N_RANGE[1] + 1))
        return diced_mix(rng, n_pieces=n, size_range=DICED_SIZE_RANGE)
    raise InvalidParameterError(f"layout must be one of {LAYOUTS}, got {layout!r}")


# The Block scenes of the study space (the -v0 ids') that the Block calibration of the probes
# is fitted on (``fetch_env.probes.calibration_for``): scene i is ``sample_scene("block",
# default_rng(BLOCK_CALIBRATION_SEED + i))``.  Disjoint from every seed the environments are
# evaluated on (the held-back 90000-90063, the headroom scenes from 80000).
BLOCK_CALIBRATION_SEED = 95_000


def block_foods(n: int, seed: int = BLOCK_CALIBRATION_SEED) -> list[food_space.Food]:
    """The single pieces of ``n`` Block scenes of the study space, as foods of the food space's
    form (``index`` i: the scene drawn from ``default_rng(seed + i)``).

    Raises:
        InvalidParameterError: ``n`` not in [1, 4096] or a negative ``seed``.
    """
    require_int("n", n)
    require(1 <= n <= 4096, "n", n, "in [1, 4096]")
    require_int("seed", seed)
    require(seed >= 0, "seed", seed, ">= 0")
    foods = []
    for i in range(n):
        (p,) = sample_scene("block", np.random.default_rng(seed + i))
        m = p.material
        foods.append(food_space.Food(i, p.shape, p.size, m.young, m.poisson, m.density, m.g1,
                                     m.tau1, m.mu))
    return foods


def _diced(materials: tuple[str, ...], seed: int, n: int) -> Callable[[], tuple[Piece, ...]]:
    # A fixed generator: a preset must give the same pieces every time.
    return lambda: diced_mix(np.random.default_rng(seed), n_pieces=n, materials=materials,
                             size_range=DICED_SIZE_RANGE)


# The study's scenes (docs/study.md, "Setups the study simulated"), by name for reset(options=...).
SCENE_PRESETS: Mapping[str, Callable[[], tuple[Piece, ...]]] = {
    "block": lambda: single_block(),
    "block-hard": lambda: single_block(material=PRESETS["hard-200MPa"]),
    "block-ellipsoid": lambda: single_block("ellipsoid"),
    "block-sphere": lambda: single_block("sphere"),
    **{f"row-{s * 1000:g}mm": (lambda s=s: single_row(spacing_across=s))
       for s in ROW_SPACINGS},
    "two-rows-soft": lambda: two_rows(material=PRESETS["soft-0.2MPa"]),
    "two-rows-hard": lambda: two_rows(material=PRESETS["hard-200MPa"]),
    "diced-soft": _diced(("soft-0.15MPa",), seed=0, n=6),
    "diced-mix": _diced(STUDY_LEVELS, seed=0, n=6),
}


def preset_scene(name: str) -> tuple[Piece, ...]:
    """The pieces of a named preset; the error lists the valid names."""
    if not isinstance(name, str) or name not in SCENE_PRESETS:
        raise InvalidParameterError(
            f"unknown scene preset {name!r}; choose from {', '.join(SCENE_PRESETS)}")
    return SCENE_PRESETS[name]()


def grid_scene(n_along: int, n_across: int, size: float, spacing_along: float,
               spacing_across: float, material: str) -> tuple[Piece, ...]:
    """A grid of cubes of a preset material (used by the reproduction command)."""
    return grid(n_along, n_across, size, spacing_along, spacing_across, PRESETS[material])


def layout_features(pieces: tuple[Piece, ...]) -> dict[str, float]:
    """What a camera over the plate would tell: count, sizes, spacing, mass (SI units).

    Spacing is the smallest gap between the footprints of two neighbouring pieces, across
    the clamp (x) and along it (y); pieces that do not overlap in the other direction are
    not neighbours there.  With one piece both spacings are reported as ``NO_NEIGHBOUR``.
    """
    require_pieces("pieces", pieces)
    ext = np.array([p.extents for p in pieces])
    xy = np.array([[p.x, p.y] for p in pieces])
    across, along = NO_NEIGHBOUR, NO_NEIGHBOUR
    for i in range(len(pieces)):
        for j in range(i + 1, len(pieces)):
            gap = np.abs(xy[i] - xy[j]) - (ext[i, :2] + ext[j, :2]) / 2
            if gap[1] < 0:  # side by side across the clamp (overlapping in y)
                across = min(across, max(float(gap[0]), 0.0))
            if gap[0] < 0:  # one behind the other along the clamp
                along = min(along, max(float(gap[1]), 0.0))
    lo = xy - ext[:, :2] / 2
    hi = xy + ext[:, :2] / 2
    return {
        "n_pieces": float(len(pieces)),
        "mean_size": float(np.mean([p.size for p in pieces])),
        "max_height": float(ext[:, 2].max()),
        "min_spacing_across": across,
        "min_spacing_along": along,
        "span_along": float(hi[:, 1].max() - lo[:, 1].min()),
        "total_mass": float(sum(p.mass for p in pieces)),
    }


NO_NEIGHBOUR = 0.005  # [m] spacing reported when no neighbour exists (5 mm: "far")
