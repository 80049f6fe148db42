"""Food pieces and how they lie on the plate: single block, rows, diced mixes.

Coordinates: the plate's top surface is z = 0; the half-spoons clamp along y (the clamp
direction) and their blades are wide along x (across the clamp direction).
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np

from fetch_env.errors import InvalidParameterError, require, require_finite, require_int
from fetch_env.materials import PRESETS, Material

Shape = Literal["cube", "ellipsoid", "sphere"]
SHAPES: tuple[str, ...] = ("cube", "ellipsoid", "sphere")
MIN_SIZE, MAX_SIZE = 0.006, 0.025  # [m] the supported piece sizes
# An ellipsoid of nominal size s has extents (x, y, z) = s * ELLIPSOID_ASPECT: long along the
# blade (x), so that it presses a larger area against the half-spoons than a sphere does.
ELLIPSOID_ASPECT = (1.0, 0.75, 0.6)
MAX_GRID = 16  # most pieces per row or column of a grid
PLATE_HALF_WIDTH = 0.1  # [m] the plate of assets/fetch_base.xml is 0.2 m square
MAX_DICED_SPACING = 0.01  # [m] widest gap between the pieces of a diced mix


@dataclass(frozen=True)
class Piece:
    """One food piece resting on the plate.

    Attributes:
        shape: "cube", "ellipsoid" or "sphere".
        size: nominal size [m] (cube edge, sphere diameter, ellipsoid long axis), 6 to 25 mm.
        material: its :class:`Material`.
        x, y: centre on the plate [m], within +-``PLATE_HALF_WIDTH``; y is the clamp
            direction.
    """

    shape: Shape = "cube"
    size: float = 0.015
    material: Material = PRESETS["soft-0.2MPa"]
    x: float = 0.0
    y: float = 0.0

    def __post_init__(self) -> None:
        # (a str first: ``in`` would compare a numpy array element-wise and raise)
        require(isinstance(self.shape, str) and self.shape in SHAPES, "shape", self.shape,
                f"one of {SHAPES}")
        require_finite("size", self.size)
        require(MIN_SIZE <= self.size <= MAX_SIZE, "size", self.size,
                f"in [{MIN_SIZE}, {MAX_SIZE}] m (6 to 25 mm)")
        for name in ("x", "y"):
            value = getattr(self, name)
            require_finite(name, value)
            require(abs(value) <= PLATE_HALF_WIDTH, name, value,
                    f"on the plate, in [-{PLATE_HALF_WIDTH}, {PLATE_HALF_WIDTH}] m")
        require(isinstance(self.material, Material), "material", self.material, "a Material")

    @property
    def extents(self) -> np.ndarray:
        """Full extents (x, y, z) [m] of the undeformed piece."""
        if self.shape == "ellipsoid":
            return self.size * np.asarray(ELLIPSOID_ASPECT)
        return np.full(3, self.size)

    @property
    def volume(self) -> float:
        e = self.extents
        return float(np.prod(e) * (np.pi / 6 if self.shape != "cube" else 1.0))

    @property
    def mass(self) -> float:
        return self.volume * self.material.density

    @property
    def centre(self) -> np.ndarray:
        """Centre of the resting piece [m]."""
        return np.array([self.x, self.y, self.extents[2] / 2])

    def support(self, direction: np.ndarray) -> float:
        """Support function max_p p . n over the undeformed piece (exact per shape)."""
        n = np.asarray(direction, float)
        half = self.extents / 2
        if self.shape == "cube":
            return float(self.centre @ n + np.abs(n) @ half)
        return float(self.centre @ n + np.sqrt((half**2) @ (n**2)))

    def to_dict(self) -> dict[str, Any]:
        return {"shape": self.shape, "size": self.size, "x": self.x, "y": self.y,
                "material": self.material.to_dict()}


def check_no_overlap(pieces: tuple[Piece, ...] | list[Piece]) -> None:
    """Reject pieces whose footprints overlap (bounding boxes in x and y).

    Touching (zero gap) is allowed; any overlap is an error naming both pieces.
    """
    require(isinstance(pieces, tuple | list) and len(pieces) >= 1, "pieces", pieces,
            "a non-empty sequence of Piece")
    for i, p in enumerate(pieces):
        require(isinstance(p, Piece), f"pieces[{i}]", p, "a Piece")
    for (i, a), (j, b) in itertools.combinations(enumerate(pieces), 2):
        gap = np.abs(np.array([a.x - b.x, a.y - b.y])) - (a.extents[:2] + b.extents[:2]) / 2
        if np.all(gap < -1e-9):
            raise InvalidParameterError(
                f"pieces {i} and {j} overlap (at x,y = ({a.x:g}, {a.y:g}) and ({b.x:g}, {b.y:g}) "
                f"with extents {a.extents[:2].round(4).tolist()} and "
                f"{b.extents[:2].round(4).tolist()} m)")


def single_block(shape: Shape = "cube", size: float = 0.015,
                 material: Material | None = None) -> tuple[Piece, ...]:
    """One piece at the origin (the study's block experiments)."""
    return (Piece(shape, size, PRESETS["soft-0.2MPa"] if material is None else material),)


def grid(n_along: int, n_across: int, size: float, spacing_along: float,
         spacing_across: float, material: Material | None = None,
         shape: Shape = "cube") -> tuple[Piece, ...]:
    """Cubes in ``n_along`` rows along the clamp direction (y) of ``n_across`` pieces each (x).

    ``spacing_along`` is the gap between rows (along y), ``spacing_across`` the gap between
    neighbours within a row (along x) [m]; the grid is centred on the origin.
    """
    for name, count in (("n_along", n_along), ("n_across", n_across)):
        require_int(name, count)
        # (no scene holds more: the blades are 48 mm wide, the smallest piece 6 mm)
        require(1 <= count <= MAX_GRID, name, count, f"in [1, {MAX_GRID}]")
    for name, gap in (("spacing_along", spacing_along), ("spacing_across", spacing_across)):
        require_finite(name, gap)
        require(gap >= 0, name, gap, ">= 0 m")
    mat = PRESETS["soft-0.2MPa"] if material is None else material
    probe = Piece(shape, size, mat)
    ex, ey = probe.extents[:2]
    xs = (np.arange(n_across) - (n_across - 1) / 2) * (ex + spacing_across)
    ys = (np.arange(n_along) - (n_along - 1) / 2) * (ey + spacing_along)
    return tuple(Piece(shape, size, mat, float(x), float(y)) for y in ys for x in xs)


def single_row(spacing_across: float = 0.001, n: int = 3, size: float = 0.012,
               spacing_along: float = 0.001, material: Material | None = None
               ) -> tuple[Piece, ...]:
    """The study's single row: ``n`` cubes side by side across the clamp direction.

    The study keeps 1 mm along the clamp direction and varies the spacing across it
    (1 / 0.5 / 0.3 / 0.1 mm); with a single row the along-spacing separates nothing and is
    kept only to describe the layout.
    """
    del spacing_along
    _check_row_count(n)
    return grid(1, n, size, 0.001, spacing_across, material)


def two_rows(material: Material | None = None, n: int = 3, size: float = 0.012,
             spacing_along: float = 0.001, spacing_across: float = 0.00001
             ) -> tuple[Piece, ...]:
    """The study's two rows: 2 x ``n`` cubes, 1 mm along and 0.01 mm across the clamp."""
    _check_row_count(n)
    return grid(2, n, size, spacing_along, spacing_across, material)


def _check_row_count(n: int) -> None:
    """A row's ``n`` named as the caller gave it (``grid`` would call it ``n_across``)."""
    require_int("n", n)
    require(1 <= n <= MAX_GRID, "n", n, f"in [1, {MAX_GRID}]")


def diced_mix(rng: np.random.Generator, n_pieces: int | None = None,
              materials: tuple[str, ...] | None = None,
              size_range: tuple[float, float] = (0.007, 0.010),
              spacing: float = 0.0005) -> tuple[Piece, ...]:
    """A diced mix of mixed shapes and stiffnesses packed on a jittered grid.

    ``n_pieces``: 1 to 16 pieces (default: 6 to 12, drawn from ``rng``); up to 8 lie in two
    rows along the clamp direction (one row for a single piece), more in three.  Every random
    choice comes from ``rng``.  ``materials`` names presets to draw from (default: the
    study's five levels); ``size_range`` bounds the nominal sizes, within 6 to 25 mm;
    ``spacing`` is the gap between neighbours [m], 0 to ``MAX_DICED_SPACING`` (10 mm).
    """
    from fetch_env.materials import STUDY_LEVELS

    require(isinstance(rng, np.random.Generator), "rng", rng, "a numpy.random.Generator")
    if n_pieces is not None:
        require_int("n_pieces", n_pieces)
    n = int(n_pieces if n_pieces is not None else rng.integers(6, 13))
    require(1 <= n <= 16, "n_pieces", n, "in [1, 16]")
    if materials is None:
        names: tuple[str, ...] | list[str] = STUDY_LEVELS
    else:
        require(isinstance(materials, tuple | list) and len(materials) >= 1, "materials",
                materials, "a non-empty tuple of preset names")
        names = materials
    for name in names:
        require(isinstance(name, str) and name in PRESETS, "materials", name,
                f"a preset name from {sorted(PRESETS)}")
    require(isinstance(size_range, tuple | list) and len(size_range) == 2, "size_range",
            size_range, "a (low, high) pair [m]")
    lo, hi = size_range
    require_finite("size_range[0]", lo)
    require_finite("size_range[1]", hi)
    require(MIN_SIZE <= lo <= hi <= MAX_SIZE, "size_range", size_range,
            "within [0.006, 0.025] m with low <= high")
    require_finite("spacing", spacing)
    # (at most 10 mm: diced food lies close, and 16 pieces of 25 mm then stay on the plate)
    require(0 <= spacing <= MAX_DICED_SPACING, "spacing", spacing,
            f"in [0, {MAX_DICED_SPACING}] m")
    # Every row must hold a piece (an empty row has no depth): a single piece lies alone.
    n_along = min(n, 2) if n <= 8 else 3
    n_across = int(np.ceil(n / n_along))
    cells = [(r, c) for r in range(n_along) for c in range(n_across)][:n]
    drawn = [(str(rng.choice(SHAPES)), float(rng.uniform(lo, hi)), PRESETS[str(rng.choice(names))])
             for _ in cells]
    extents = [Piece(shape, size, mat).extents for shape, size, mat in drawn]
    # Packed like diced food on a plate: each row along the clamp direction (y) is as deep as
    # its deepest piece, each piece as wide as it is (x), neighbours `spacing` apart, plus a
    # small jitter (a quarter of the spacing) that can never close a gap.
    row_depth = [max(extents[k][1] for k, (r, _) in enumerate(cells) if r == row)
                 for row in range(n_along)]
    row_y = np.cumsum([0.0] + [row_depth[i] / 2 + row_depth[i + 1] / 2 + spacing
                               for i in range(n_along - 1)])
    row_y -= row_y.mean()
    pieces: list[Piece] = []
    for row in range(n_along):
        members = [k for k, (r, _) in enumerate(cells) if r == row]
        widths = [extents[k][0] for k in members]
        x = np.cumsum([0.0] + [widths[i] / 2 + widths[i + 1] / 2 + spacing
                               for i in range(len(members) - 1)])
        x -= x.mean()
        for k, xk in zip(members, x, strict=True):
            shape, size, mat = drawn[k]
            jx, jy = rng.uniform(-spacing / 4, spacing / 4, size=2)
            pieces.append(Piece(shape, size, mat, float(xk + jx), float(row_y[row] + jy)))
    check_no_overlap(pieces)
    return tuple(pieces)
