"""Every documented range of the Python API gives a result or the package's typed error.

Hypothesis sweeps each documented range (docstrings and ``require(...)`` checks), its
boundaries, values just outside it, far outside it, wrong types, NaN and infinities.  A call
may only return a valid result or raise the package's own error class -- exactly
:class:`fetch_env.errors.InvalidParameterError` for bad simulator input,
:class:`estimators.EstimationError` for unusable estimator input, and
:class:`fetch_env.errors.SimulationDivergedError` for physics that blew up -- never a bare
``ValueError``/``TypeError``/``KeyError`` from deep inside: a caller (the CLI, an RL training
loop) catches the typed errors to report or skip one bad case, and anything else kills the run.

Where the range is exact (the constructors) the test is an oracle: a value inside must be
accepted and kept, one outside must be refused with an error naming the parameter.

Every test states its number of examples; all are derandomized (the same examples on every
run, no example database), so a failure reproduces.  The one physics property runs a few
examples by default and more under ``-m slow``.  Bugs in modules other code owns are marked
``xfail(strict=True)`` with the reproducer in the reason: fixing one turns its test red, as a
reminder to drop the mark.
"""

from __future__ import annotations

import itertools
import math
import warnings
from collections.abc import Callable
from dataclasses import dataclass, fields
from typing import Any

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

import estimators
from estimators import (
    ClampGeometry,
    EstimationError,
    FrictionEstimate,
    HoldEstimate,
    SLSParams,
    ViscoelasticEstimate,
    estimate_friction,
    estimate_from_hold,
    estimate_full_fit,
    estimate_three_step,
    moment_trace,
    steady_moment,
)
from estimators.slip_level import SLIP_FORCES, read_mu
from estimators.sls import clamp_angle
from fetch_env import layouts, spaces
from fetch_env.controller import FetchAction, FetchSimulator, SimResult, TimeScale
from fetch_env.errors import InvalidParameterError, SimulationDivergedError
from fetch_env.layouts import (
    MAX_DICED_SPACING,
    MAX_GRID,
    MAX_SIZE,
    MIN_SIZE,
    PLATE_HALF_WIDTH,
    SHAPES,
    Piece,
    check_no_overlap,
)
from fetch_env.materials import PRESETS, STUDY_LEVELS, Material, preset
from fetch_env.probes import ProbeConfig
from fetch_env.scene import Geometry


def examples(n: int) -> settings:
    """``n`` derandomized examples, no deadline (the first call compiles or imports), no
    example database (the same examples on every machine)."""
    return settings(max_examples=n, derandomize=True, deadline=None, database=None,
                    suppress_health_check=[HealthCheck.too_slow])


# --------------------------------------------------------------------------------------------
# the typed errors


def test_the_typed_errors_are_the_documented_classes() -> None:
    """Bad input is a ``ValueError`` (so generic callers catch it), divergence a
    ``RuntimeError`` carrying the scene and action to reproduce it."""
    assert issubclass(InvalidParameterError, ValueError)
    assert issubclass(EstimationError, ValueError)
    assert estimators.EstimationError is EstimationError
    assert issubclass(SimulationDivergedError, RuntimeError)
    assert not issubclass(SimulationDivergedError, ValueError)


# --------------------------------------------------------------------------------------------
# ranges and the values around them


@dataclass(frozen=True)
class Range:
    """A documented numeric range; ``None`` bounds are open-ended (but finite)."""

    lo: float | None
    hi: float | None
    lo_open: bool = False
    hi_open: bool = False

    def contains(self, value: Any) -> bool:
        """Whether ``value`` is a finite real number (not bool) inside the range."""
        if isinstance(value, bool | np.bool_) or not isinstance(value, int | float | np.floating):
            return False
        if not math.isfinite(value):
            return False
        if self.lo is not None and (value <= self.lo if self.lo_open else value < self.lo):
            return False
        return self.hi is None or (value < self.hi if self.hi_open else value <= self.hi)


# Values that no numeric parameter accepts: wrong types, NaN and the infinities.
JUNK: tuple[Any, ...] = (None, "0.01", b"1", [0.01], (0.01, 0.02), {}, 0.01j, 1 + 0j,
                         np.array([0.01, 0.02]), True, False, math.nan, math.inf, -math.inf,
                         object())
junk = st.sampled_from(JUNK)


def around(r: Range) -> st.SearchStrategy[Any]:
    """Values inside ``r`` (its boundaries included), one ulp and far outside it, and junk."""
    lo = -1e6 if r.lo is None else r.lo
    hi = 1e6 if r.hi is None else r.hi
    edges: list[float] = []
    for b in (r.lo, r.hi):
        if b is not None:
            edges += [b, float(np.nextafter(b, -np.inf)), float(np.nextafter(b, np.inf)),
                      b - abs(b) * 1e-9 - 1e-12, b + abs(b) * 1e-9 + 1e-12]
    far = [lo - 1.0, lo - 1e3, hi + 1.0, hi * 10 + 1.0, -1e300, 1e300]
    return st.one_of(
        st.floats(lo, hi, allow_nan=False, allow_infinity=False),
        st.sampled_from(edges + far),
        st.integers(-3, 3),
        junk,
    )


def refused(exc_info: pytest.ExceptionInfo[BaseException], cls: type[Exception],
            name: str) -> None:
    """The error is exactly ``cls`` (not a subclass, not a bare ValueError) and names
    ``name``."""
    assert type(exc_info.value) is cls, repr(exc_info.value)
    assert name in str(exc_info.value), str(exc_info.value)


def check_field(factory: Callable[..., Any], ranges: dict[str, Range], name: str,
                value: Any) -> Any:
    """Build ``factory(**{name: value})``: accepted and kept iff ``value`` is in range, else
    :class:`InvalidParameterError` naming ``name``."""
    if ranges[name].contains(value):
        obj = factory(**{name: value})
        assert getattr(obj, name) == value
        return obj
    with pytest.raises(InvalidParameterError) as exc_info:
        factory(**{name: value})
    refused(exc_info, InvalidParameterError, name)
    return None


def one_field(ranges: dict[str, Range]) -> st.SearchStrategy[tuple[str, Any]]:
    """A field name and a value around its range."""
    return st.sampled_from(sorted(ranges)).flatmap(
        lambda n: st.tuples(st.just(n), around(ranges[n])))


def inside(r: Range) -> st.SearchStrategy[float]:
    """Finite floats inside ``r`` (open ends excluded)."""
    lo = -1e6 if r.lo is None else r.lo
    hi = 1e6 if r.hi is None else r.hi
    return st.floats(lo, hi, exclude_min=r.lo_open, exclude_max=r.hi_open, allow_nan=False,
                     allow_infinity=False)


# --------------------------------------------------------------------------------------------
# materials

MATERIAL_RANGES = {
    "young": Range(0.0, 1e10, lo_open=True),
    "poisson": Range(0.0, 0.5, hi_open=True),
    "density": Range(10.0, 5e4),
    "g1": Range(0.0, 1.0, hi_open=True),
    "tau1": Range(0.0, 1e6, lo_open=True),
    "mu": Range(0.0, 10.0),
    "plate_mu": Range(0.0, 10.0),
    "yield_strain": Range(0.0, None),
}


@examples(400)
@given(one_field(MATERIAL_RANGES))
def test_material_field_in_range_or_typed_error(field_value: tuple[str, Any]) -> None:
    """Each of Material's numbers: accepted iff inside its documented range."""
    name, value = field_value
    mat = check_field(Material, MATERIAL_RANGES, name, value)
    if mat is not None:
        assert hash(mat) == hash(Material(**{name: value}))


@examples(100)
@given(st.fixed_dictionaries({k: inside(r) for k, r in MATERIAL_RANGES.items()}))
def test_material_anywhere_in_its_ranges_is_valid(kwargs: dict[str, float]) -> None:
    """Any combination of in-range values is a material, whose relaxation modulus stays
    between its long-term and instantaneous moduli."""
    mat = Material(**kwargs)
    assert mat.young_long_term <= mat.relaxation_modulus(1.0) <= mat.young
    assert Material(**mat.to_dict()) == mat  # (to_dict's list of Prony terms is normalised)


prony_term = st.tuples(st.floats(0.0, 0.6, exclude_max=True), st.floats(1e-3, 1e3))


@examples(150)
@given(g1=st.floats(0.0, 0.9), terms=st.lists(prony_term, max_size=3),
       as_lists=st.booleans())
def test_extra_prony_terms_sum_below_one(g1: float, terms: list[tuple[float, float]],
                                          as_lists: bool) -> None:
    """Extra Prony terms: valid iff all g sum below 1; given as lists they are stored as
    tuples, so the material stays hashable (scenes are cached by it)."""
    given_terms = [list(t) for t in terms] if as_lists else tuple(terms)
    if g1 + sum(g for g, _ in terms) < 1:
        mat = Material(g1=g1, extra_prony=given_terms)  # type: ignore[arg-type]
        assert mat.extra_prony == tuple(terms)
        hash(mat)
    else:
        with pytest.raises(InvalidParameterError) as exc_info:
            Material(g1=g1, extra_prony=given_terms)  # type: ignore[arg-type]
        refused(exc_info, InvalidParameterError, "sum of Prony g")


@examples(60)
@given(st.one_of(junk, st.lists(junk.filter(lambda v: not isinstance(v, tuple)), min_size=1,
                                max_size=2),
                 st.tuples(st.floats(0.1, 0.5), junk).map(lambda t: (t,)),
                 st.tuples(junk, st.floats(0.1, 5.0)).map(lambda t: (t,))))
def test_malformed_extra_prony_is_a_typed_error(value: Any) -> None:
    """Not a sequence of (g, tau) pairs of numbers: refused, naming the Prony terms."""
    with pytest.raises(InvalidParameterError) as exc_info:
        Material(extra_prony=value)
    assert type(exc_info.value) is InvalidParameterError
    assert any(k in str(exc_info.value) for k in ("extra_prony", "g2", "tau2"))


@examples(40)
@given(st.one_of(st.sampled_from(sorted(PRESETS)), st.text(max_size=12), junk))
def test_preset_lookup(name: Any) -> None:
    """A preset name gives its material; anything else the error listing the names."""
    if isinstance(name, str) and name in PRESETS:
        assert preset(name) is PRESETS[name]
    else:
        with pytest.raises(InvalidParameterError) as exc_info:
            preset(name)
        refused(exc_info, InvalidParameterError, "soft-0.2MPa")


@examples(30)
@given(st.one_of(st.sampled_from(["colour", "E", "youngs"]), st.text(min_size=1, max_size=8)))
def test_material_with_unknown_field_is_a_typed_error(key: str) -> None:
    """``Material.with_`` of a field that does not exist names it."""
    assume(key not in {f.name for f in fields(Material)})
    with pytest.raises(InvalidParameterError) as exc_info:
        PRESETS["soft-0.2MPa"].with_(**{key: 1.0})
    refused(exc_info, InvalidParameterError, repr(key))


@examples(30)
@given(st.one_of(st.integers(), junk.filter(lambda v: not isinstance(v, str))))
def test_material_name_must_be_text(name: Any) -> None:
    """The label is a str; a number or other object is refused."""
    with pytest.raises(InvalidParameterError) as exc_info:
        Material(name=name)
    refused(exc_info, InvalidParameterError, "name")


# --------------------------------------------------------------------------------------------
# pieces

SIZE = Range(MIN_SIZE, MAX_SIZE)
shapes = st.one_of(st.sampled_from(SHAPES), st.sampled_from(["Cube", "box", "", "spheres"]),
                   junk)
materials = st.one_of(st.sampled_from(sorted(PRESETS)).map(PRESETS.__getitem__),
                      st.sampled_from([1, "soft-0.2MPa", {"young": 1e5}, ()]))


PLATE = Range(-PLATE_HALF_WIDTH, PLATE_HALF_WIDTH)
positions = around(PLATE)


@examples(300)
@given(shape=shapes, size=around(SIZE), material=materials, x=positions, y=positions)
def test_piece_in_range_or_typed_error(shape: Any, size: Any, material: Any, x: Any,
                                        y: Any) -> None:
    """A piece is built iff its shape is known, its size within 6 to 25 mm, its material a
    Material and its centre on the plate; its extents, mass and centre are then finite."""
    ok = (isinstance(shape, str) and shape in SHAPES and SIZE.contains(size)
          and isinstance(material, Material) and PLATE.contains(x) and PLATE.contains(y))
    if ok:
        p = Piece(shape, size, material, x, y)
        assert np.all(np.isfinite(p.extents)) and p.mass > 0
        assert np.all(np.isfinite(p.centre))
    else:
        with pytest.raises(InvalidParameterError) as exc_info:
            Piece(shape, size, material, x, y)
        assert type(exc_info.value) is InvalidParameterError


# --------------------------------------------------------------------------------------------
# layouts

counts = st.one_of(st.integers(-2, 8),
                   st.sampled_from([2.5, 3.0, "3", np.int64(2), MAX_GRID, MAX_GRID + 1, 10**9]),
                   junk)
spacings = around(Range(0.0, None)).filter(lambda v: not (isinstance(v, float) and v > 1.0))


def neighbours_apart(pieces: tuple[Piece, ...], spacing: float) -> None:
    """Consecutive pieces of a row are ``spacing`` apart, edge to edge."""
    xs = sorted(pieces, key=lambda p: p.x)
    for a, b in itertools.pairwise(xs):
        gap = (b.x - a.x) - (a.extents[0] + b.extents[0]) / 2
        assert gap == pytest.approx(spacing, abs=1e-12)


@examples(200)
@given(shape=shapes, size=around(SIZE),
       material=st.one_of(st.none(), materials))
def test_single_block(shape: Any, size: Any, material: Any) -> None:
    """One piece at the origin, or the error naming what was wrong."""
    ok = (isinstance(shape, str) and shape in SHAPES and SIZE.contains(size)
          and (material is None or isinstance(material, Material)))
    if ok:
        (p,) = layouts.single_block(shape, size, material)
        assert (p.x, p.y) == (0.0, 0.0)
    else:
        with pytest.raises(InvalidParameterError) as exc_info:
            layouts.single_block(shape, size, material)
        assert type(exc_info.value) is InvalidParameterError


def _valid_count(n: Any) -> bool:
    """Whether ``n`` is a documented count: an integer (not bool) in [1, MAX_GRID]."""
    return (isinstance(n, int | np.integer) and not isinstance(n, bool | np.bool_)
            and 1 <= n <= MAX_GRID)


def _on_plate(n: int, width: float, gap: float) -> bool:
    """Whether ``n`` pieces ``width`` wide, ``gap`` apart and centred on the origin keep
    their centres on the plate (computed as ``layouts.grid`` places them)."""
    return bool(np.all(np.abs((np.arange(n) - (n - 1) / 2) * (width + gap))
                       <= PLATE_HALF_WIDTH))


@examples(250)
@given(n=counts, spacing=spacings, size=around(Range(0.006, 0.025)))
def test_single_row(n: Any, spacing: Any, size: Any) -> None:
    """``n`` >= 1 cubes in a row, ``spacing`` apart; a fractional, textual or missing count,
    a negative / non-finite spacing or a row wider than the plate is refused."""
    ok = (_valid_count(n) and Range(0.0, None).contains(spacing) and SIZE.contains(size)
          and _on_plate(n, size, spacing))
    if ok:
        pieces = layouts.single_row(spacing_across=spacing, n=n, size=size)
        assert len(pieces) == n
        check_no_overlap(pieces)
        neighbours_apart(pieces, spacing)
    else:
        with pytest.raises(InvalidParameterError) as exc_info:
            layouts.single_row(spacing_across=spacing, n=n, size=size)
        assert type(exc_info.value) is InvalidParameterError


@examples(250)
@given(n=counts, along=spacings, across=spacings, size=around(Range(0.006, 0.025)))
def test_two_rows(n: Any, along: Any, across: Any, size: Any) -> None:
    """2 x ``n`` cubes in two rows ``along`` apart, neighbours ``across`` apart."""
    ok = (_valid_count(n) and Range(0.0, None).contains(along)
          and Range(0.0, None).contains(across) and SIZE.contains(size)
          and _on_plate(2, size, along) and _on_plate(n, size, across))
    if ok:
        pieces = layouts.two_rows(n=n, size=size, spacing_along=along, spacing_across=across)
        assert len(pieces) == 2 * n
        check_no_overlap(pieces)
        ys = sorted({p.y for p in pieces})
        assert len(ys) == 2 and ys[1] - ys[0] - size == pytest.approx(along, abs=1e-12)
        neighbours_apart(tuple(p for p in pieces if p.y == ys[0]), across)
    else:
        with pytest.raises(InvalidParameterError) as exc_info:
            layouts.two_rows(n=n, size=size, spacing_along=along, spacing_across=across)
        assert type(exc_info.value) is InvalidParameterError


@examples(150)
@given(n_along=counts, n_across=counts, shape=st.sampled_from(SHAPES),
       material=st.one_of(st.none(), materials))
def test_grid(n_along: Any, n_across: Any, shape: str, material: Any) -> None:
    """``n_along`` x ``n_across`` pieces that never overlap, or a typed error."""
    ok = (_valid_count(n_along) and _valid_count(n_across)
          and (material is None or isinstance(material, Material)))
    if ok:
        pieces = layouts.grid(n_along, n_across, 0.01, 0.001, 0.0005, material, shape)
        assert len(pieces) == n_along * n_across
        check_no_overlap(pieces)
    else:
        with pytest.raises(InvalidParameterError) as exc_info:
            layouts.grid(n_along, n_across, 0.01, 0.001, 0.0005, material, shape)
        assert type(exc_info.value) is InvalidParameterError


size_bounds = around(SIZE)
preset_names = st.sampled_from(sorted(PRESETS))
material_choices = st.one_of(
    st.none(),
    st.lists(preset_names, min_size=1, max_size=4, unique=True).map(tuple),
    st.lists(st.one_of(preset_names, st.sampled_from(["soft", "", "HARD-200MPA"]), junk),
             min_size=0, max_size=3).map(tuple),
    st.sampled_from(["soft-0.2MPa", 3]),
)
diced_counts = st.one_of(st.none(), st.integers(-1, 18),
                         st.sampled_from([1.0, 2.5, "6", np.int32(5), True]), junk)


def _valid_materials(m: Any) -> bool:
    """Whether ``m`` is a documented ``materials``: None or a non-empty tuple of presets."""
    return m is None or (isinstance(m, tuple) and len(m) >= 1
                         and all(isinstance(k, str) and k in PRESETS for k in m))


@examples(400)
@given(seed=st.integers(0, 2**32 - 1), n=diced_counts, lo=size_bounds, hi=size_bounds,
       spacing=around(Range(0.0, MAX_DICED_SPACING)), names=material_choices)
def test_diced_mix(seed: int, n: Any, lo: Any, hi: Any, spacing: Any, names: Any) -> None:
    """1 to 16 non-overlapping pieces with sizes in ``size_range`` and materials from
    ``materials``, the same for the same seed; anything outside those ranges, a typed error."""
    rng = np.random.default_rng(seed)
    ok = ((n is None or (1 <= n <= 16 if _valid_count(n) else False))
          and SIZE.contains(lo) and SIZE.contains(hi) and lo <= hi
          and Range(0.0, MAX_DICED_SPACING).contains(spacing) and _valid_materials(names))
    kwargs = {"n_pieces": n, "size_range": (lo, hi), "spacing": spacing, "materials": names}
    if ok:
        pieces = layouts.diced_mix(rng, **kwargs)
        assert 1 <= len(pieces) <= 16
        if n is not None:
            assert len(pieces) == n
        else:
            assert 6 <= len(pieces) <= 12
        check_no_overlap(pieces)
        allowed = {PRESETS[k] for k in (names or STUDY_LEVELS)}
        for p in pieces:
            assert lo <= p.size <= hi
            assert p.material in allowed
        assert layouts.diced_mix(np.random.default_rng(seed), **kwargs) == pieces
    else:
        with pytest.raises(InvalidParameterError) as exc_info:
            layouts.diced_mix(rng, **kwargs)
        assert type(exc_info.value) is InvalidParameterError


@examples(100)
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(1, 16),
       bounds=st.lists(st.floats(MIN_SIZE, MAX_SIZE), min_size=2, max_size=2).map(sorted),
       spacing=st.floats(0.0, 0.005),
       names=st.lists(preset_names, min_size=1, max_size=6, unique=True).map(tuple))
def test_diced_mix_anywhere_in_its_ranges(seed: int, n: int, bounds: list[float],
                                          spacing: float, names: tuple[str, ...]) -> None:
    """Inside every documented range at once: ``n`` pieces, no overlap, each within
    ``size_range`` and of a named material, any two at least ``spacing / 2`` apart along x
    or y (the jitter moves each by at most a quarter of the spacing)."""
    lo, hi = bounds
    pieces = layouts.diced_mix(np.random.default_rng(seed), n_pieces=n, size_range=(lo, hi),
                               spacing=spacing, materials=names)
    assert len(pieces) == n
    check_no_overlap(pieces)
    assert all(lo <= p.size <= hi and p.material.name in names for p in pieces)
    for a, b in itertools.combinations(pieces, 2):
        gap = np.abs([a.x - b.x, a.y - b.y]) - (a.extents[:2] + b.extents[:2]) / 2
        assert gap.max() >= spacing / 2 - 1e-12


@pytest.mark.parametrize("n", range(1, 17))
def test_diced_mix_every_count(n: int) -> None:
    """Every documented count, 1 to 16, over a few seeds: that many non-overlapping pieces,
    any two at least half the default 0.5 mm spacing apart.  (A single piece lies in a row of
    its own: a second, empty row has no depth to lay out.)"""
    for seed in (0, 1, 7, 12345):
        pieces = layouts.diced_mix(np.random.default_rng(seed), n_pieces=n)
        assert len(pieces) == n
        check_no_overlap(pieces)
        for a, b in itertools.combinations(pieces, 2):
            gap = np.abs([a.x - b.x, a.y - b.y]) - (a.extents[:2] + b.extents[:2]) / 2
            assert gap.max() >= 0.0005 / 2 - 1e-12
        assert all(MIN_SIZE <= p.size <= MAX_SIZE for p in pieces)
        assert all(p.material in {PRESETS[k] for k in STUDY_LEVELS} for p in pieces)


@examples(20)
@given(st.one_of(junk, st.integers(), st.just(np.random.RandomState(0))))
def test_diced_mix_needs_a_generator(rng: Any) -> None:
    """The randomness must come from a ``numpy.random.Generator``."""
    with pytest.raises(InvalidParameterError) as exc_info:
        layouts.diced_mix(rng, n_pieces=3)
    refused(exc_info, InvalidParameterError, "rng")


# --------------------------------------------------------------------------------------------
# the robot's action, the end-effector, the time scale

ACTION_RANGES = {
    "theta_d": Range(0.0, 0.3, lo_open=True),
    "omega": Range(1e-3, 2.0),
    "lift_speed": Range(1e-4, 0.1),
    "hold": Range(0.0, 600.0),
    "lift_height": Range(0.0, 0.05, lo_open=True),
    "air_hold": Range(0.0, 60.0),
    "settle": Range(0.05, 5.0),
    "slide_distance": Range(0.0, 0.02, lo_open=True),
    "slide_time": Range(0.0, 120.0, lo_open=True),
}
GEOMETRY_RANGES = {
    "blade_length": Range(0.03, 0.2),
    "blade_width": Range(0.01, 0.1),
    "tip_clearance": Range(0.0, 0.02),
    "gap": Range(0.0, 0.01),
    "contact_timeconst": Range(0.001, 0.1),
}
TIME_SCALE_RANGES = {
    "factor": Range(1.0, 50.0),
    "realtime": Range(0.0, None),
    "growth": Range(0.0, 0.5),
}


@examples(400)
@given(one_field(ACTION_RANGES))
def test_fetch_action_field_in_range_or_typed_error(field_value: tuple[str, Any]) -> None:
    """Each FetchAction setting: accepted iff inside its documented range."""
    check_field(FetchAction, ACTION_RANGES, *field_value)


@examples(200)
@given(one_field(GEOMETRY_RANGES))
def test_geometry_field_in_range_or_typed_error(field_value: tuple[str, Any]) -> None:
    """Each Geometry length (and the contact time constant): accepted iff in range."""
    check_field(Geometry, GEOMETRY_RANGES, *field_value)


@examples(200)
@given(one_field(TIME_SCALE_RANGES))
def test_time_scale_field_in_range_or_typed_error(field_value: tuple[str, Any]) -> None:
    """Each TimeScale setting: accepted iff in range; its steps then cover the hold."""
    ts = check_field(TimeScale, TIME_SCALE_RANGES, *field_value)
    if ts is not None and ts.realtime < 1e3:
        steps = ts.step_times(ts.realtime, 2.0, 0.005)
        assert steps.sum() == pytest.approx(2.0) and np.all(steps > 0)


@examples(60)
@given(st.fixed_dictionaries({k: inside(r) for k, r in ACTION_RANGES.items()}))
def test_fetch_action_anywhere_in_its_ranges_is_valid(kwargs: dict[str, float]) -> None:
    """All settings in range together make an action that round-trips through to_dict."""
    action = FetchAction(**kwargs)
    assert FetchAction(**action.to_dict()) == action


PROBE_FIELDS = [f.name for f in fields(ProbeConfig) if f.name != "relaxation_timestep"]


@pytest.mark.parametrize("value", [math.nan, math.inf, -1.0, "0.1"])
def test_probe_config_rejects_bad_settings(value: Any) -> None:
    """A probe setting given something that is no finite, non-negative number is refused at
    construction, naming the setting (``slip_envelope``, a name, refuses these too; explicit
    cases: a known-failing Hypothesis test would write a patch file every run)."""
    for name in PROBE_FIELDS:
        with pytest.raises(InvalidParameterError) as exc_info:
            ProbeConfig(**{name: value})
        refused(exc_info, InvalidParameterError, name)


@examples(40)
@given(strain=st.floats(0.001, 0.3), omega=st.floats(0.01, 2.0), hold=st.floats(0.05, 60.0),
       scale=st.floats(1.0, 50.0), growth=st.floats(0.0, 0.5))
def test_probe_config_in_the_env_s_ranges(strain: float, omega: float, hold: float,
                                          scale: float, growth: float) -> None:
    """The settings the env documents (probe_strain, _omega, _hold, _time_scale,
    _time_growth) make a config, and its time scale is a valid TimeScale."""
    cfg = ProbeConfig(strain=strain, omega=omega, hold=hold, hold_time_scale=scale,
                      hold_time_growth=growth)
    TimeScale(factor=cfg.hold_time_scale, growth=cfg.hold_time_growth)
    FetchAction(omega=cfg.omega, hold=cfg.hold, settle=cfg.settle)


# --------------------------------------------------------------------------------------------
# the environments' spaces


JUNK_NOT_BOOL = st.sampled_from([v for v in JUNK if not isinstance(v, bool)])


@examples(150)
@given(st.one_of(
    st.lists(st.floats(-5, 5), min_size=3, max_size=3),
    st.lists(st.floats(allow_nan=True, allow_infinity=True), min_size=0, max_size=4),
    junk, st.lists(JUNK_NOT_BOOL, min_size=3, max_size=3)))
def test_actions_map_into_their_ranges_or_typed_error(action: Any) -> None:
    """An action of 3 finite numbers maps into ACTION_RANGES (clipped); anything else is
    refused."""
    ok = (isinstance(action, list) and len(action) == 3
          and all(isinstance(v, float) and math.isfinite(v) for v in action))
    if ok:
        phys = spaces.action_to_physical(action)
        for k, (lo, hi) in spaces.ACTION_RANGES.items():
            assert lo <= phys[k] <= hi
    else:
        with pytest.raises(InvalidParameterError) as exc_info:
            spaces.action_to_physical(action)
        refused(exc_info, InvalidParameterError, "action")


@examples(150)
@given(name=st.sampled_from(spaces.ACTION_NAMES), value=st.one_of(
    st.floats(0.0, 0.5), st.floats(allow_nan=True, allow_infinity=True), junk))
def test_physical_to_action_in_range_or_typed_error(name: str, value: Any) -> None:
    """Physical values inside ACTION_RANGES map to [-1, 1] and back; others are refused."""
    phys = {"theta_d": 0.05, "omega": 0.1, "lift_speed": 0.01, name: value}
    lo, hi = spaces.ACTION_RANGES[name]
    if Range(lo, hi).contains(value):
        a = spaces.physical_to_action(**phys)
        assert np.all(np.abs(a) <= 1)
        assert spaces.action_to_physical(a)[name] == pytest.approx(value, rel=1e-6)
    else:
        with pytest.raises(InvalidParameterError) as exc_info:
            spaces.physical_to_action(**phys)
        refused(exc_info, InvalidParameterError, name)


@examples(100)
@given(st.one_of(
    st.lists(st.floats(-10, 10), min_size=len(spaces.OBS_NAMES), max_size=len(spaces.OBS_NAMES)),
    st.lists(st.floats(-10, 10), max_size=20), junk,
    st.lists(st.sampled_from([math.nan, "a", None, 1j]), min_size=len(spaces.OBS_NAMES),
             max_size=len(spaces.OBS_NAMES))))
def test_observations_decode_or_typed_error(obs: Any) -> None:
    """An observation of the right length of finite numbers decodes; anything else is
    refused."""
    ok = (isinstance(obs, list) and len(obs) == len(spaces.OBS_NAMES)
          and all(isinstance(v, float) and math.isfinite(v) for v in obs))
    if ok:
        out = spaces.decode_observation(obs)
        assert set(out) == set(spaces.OBS_NAMES)
    else:
        with pytest.raises(InvalidParameterError) as exc_info:
            spaces.decode_observation(obs)
        refused(exc_info, InvalidParameterError, "observation")


OBS_VALUES = {"K1": 5e3, "K2": 3e3, "B": 1e4, "mu": 0.3, "g1": 0.4, "tau1": 3.0,
              "visco_valid": 1.0, "friction_valid": 1.0, "n_pieces": 1.0, "mean_size": 0.015,
              "max_height": 0.015, "min_spacing_across": 0.005, "min_spacing_along": 0.005,
              "span_along": 0.015, "total_mass": 0.003}


@examples(100)
@given(name=st.sampled_from(sorted(OBS_VALUES)),
       value=st.one_of(st.floats(allow_nan=True, allow_infinity=True), junk,
                       st.just("missing")))
def test_encode_observation_or_typed_error(name: str, value: Any) -> None:
    """Estimates may be anything numeric (a wild one clears its group's flag); layout
    features must be finite; a missing or non-numeric value is refused by name."""
    values = dict(OBS_VALUES)
    missing = isinstance(value, str) and value == "missing"
    if missing:
        del values[name]
    else:
        values[name] = value
    estimated = name in spaces.VISCO_NAMES or name in spaces.FRICTION_NAMES
    flag = name in ("visco_valid", "friction_valid")
    numeric = isinstance(value, int | float)  # (bool too: a flag may be True)
    ok = (missing and flag) or (numeric and (estimated or math.isfinite(value)))
    if ok:
        obs = spaces.encode_observation(values)
        assert obs.shape == (len(spaces.OBS_NAMES),) and np.all(np.isfinite(obs))
    else:
        with pytest.raises(InvalidParameterError) as exc_info:
            spaces.encode_observation(values)
        refused(exc_info, InvalidParameterError, name)


# --------------------------------------------------------------------------------------------
# the physics: one short fetch of a drawn piece

piece_and_action = st.fixed_dictionaries({
    "shape": st.sampled_from(SHAPES),
    "size": st.floats(0.006, 0.025),
    "young": st.floats(math.log(0.0123e6), math.log(5e6)).map(math.exp),
    "g1": st.floats(0.1, 0.8),
    "tau1": st.floats(0.5, 10.0),
    "mu": st.floats(0.1, 0.8),
    "theta_d": st.floats(0.005, 0.3),
    "omega": st.floats(0.05, 2.0),
})


def short_fetch(d: dict[str, Any]) -> None:
    """Clamp a drawn piece at a drawn angle and speed, hold 0.1 s, lift 2 mm: a SimResult with
    finite traces and a fetch rate in [0, 1], or a SimulationDivergedError that carries the
    scene and the action to reproduce it."""
    mat = Material(young=d["young"], g1=d["g1"], tau1=d["tau1"], mu=d["mu"])
    pieces = (Piece(d["shape"], d["size"], mat),)
    action = FetchAction(theta_d=d["theta_d"], omega=d["omega"], hold=0.1, settle=0.05,
                         lift_height=0.002, lift_speed=0.04, air_hold=0.05)
    try:
        result = FetchSimulator(pieces).run("fetch", action)
    except SimulationDivergedError as exc:
        assert type(exc) is SimulationDivergedError
        assert exc.action == action.to_dict() and exc.scene
        return
    assert isinstance(result, SimResult)
    assert 0.0 <= result.fetch_rate <= 1.0 and 0.0 <= result.fetch_rate_mass <= 1.0
    for name, trace in result.traces.items():
        assert np.all(np.isfinite(trace)), name


@examples(6)
@given(piece_and_action)
def test_short_fetch_of_a_drawn_piece(d: dict[str, Any]) -> None:
    """A few drawn pieces and actions (the slow variant draws 200)."""
    short_fetch(d)


@pytest.mark.slow
@examples(200)
@given(piece_and_action)
def test_short_fetch_of_a_drawn_piece_slow(d: dict[str, Any]) -> None:
    """The same property over 200 drawn pieces and actions (``-m slow``, ~30 s)."""
    short_fetch(d)


SIMULATOR_RANGES = {
    "record_hz": Range(100.0, None),
    "timestep": Range(1e-4, 0.02),
    "impratio": Range(1.0, 1e4),
}


@examples(150)
@given(one_field(SIMULATOR_RANGES))
def test_simulator_settings_in_range_or_typed_error(field_value: tuple[str, Any]) -> None:
    """FetchSimulator's record rate, timestep and impratio: accepted iff in range or (the
    last two) None for the scene's own, checked at construction, before any compiling."""
    name, value = field_value
    pieces = layouts.single_block()
    if SIMULATOR_RANGES[name].contains(value) or (value is None and name != "record_hz"):
        assert getattr(FetchSimulator(pieces, **{name: value}), name) == value
    else:
        with pytest.raises(InvalidParameterError) as exc_info:
            FetchSimulator(pieces, **{name: value})
        refused(exc_info, InvalidParameterError, name)


@examples(40)
@given(experiment=st.one_of(st.sampled_from(["fetch", "relaxation", "slip"]),
                            st.sampled_from(["Fetch", "", "grasp"]), junk),
       action=st.one_of(st.none(), st.just(FetchAction()), junk),
       time_scale=st.one_of(st.none(), st.just(TimeScale()), st.just(TimeScale(factor=8.0)),
                            st.just(TimeScale(clamp_speed=0.2)), junk))
def test_run_arguments_are_checked_before_any_physics(experiment: Any, action: Any,
                                                      time_scale: Any) -> None:
    """An unknown experiment, a non-FetchAction action, a non-TimeScale time scale or a
    scaled slip (it has no hold to scale): refused by name before any scene is built."""
    ok = (isinstance(experiment, str) and experiment in ("fetch", "relaxation", "slip")
          and (action is None or isinstance(action, FetchAction))
          and (time_scale is None or isinstance(time_scale, TimeScale))
          and (time_scale is None or experiment != "slip" or not time_scale.scaled))
    assume(not ok)  # (valid runs: the physics property)
    sim = FetchSimulator(layouts.single_block())
    with pytest.raises(InvalidParameterError) as exc_info:
        sim.run(experiment, action, time_scale=time_scale)
    assert type(exc_info.value) is InvalidParameterError


@pytest.mark.parametrize(("experiment", "action"), [
    (np.array(["fetch", "slip"]), None), ("fetch", np.array([0.05, 0.1])), ("fetch", 0),
    ("fetch", [])])
def test_run_refuses_arrays_and_falsy_actions(experiment: Any, action: Any) -> None:
    """A numpy array as the experiment or the action, or a falsy non-FetchAction action, is
    an InvalidParameterError before any physics."""
    sim = FetchSimulator(layouts.single_block())
    with pytest.raises(InvalidParameterError) as exc_info:
        sim.run(experiment, action)
    assert type(exc_info.value) is InvalidParameterError


@pytest.mark.parametrize("kwargs", [{"pieces": None}, {"pieces": 5},
                                    {"pieces": layouts.single_block(), "geometry": 1}])
def test_simulator_refuses_non_pieces_and_non_geometry(kwargs: dict[str, Any]) -> None:
    """Pieces that are not a sequence of Piece, or a geometry that is not a Geometry, are an
    InvalidParameterError (at construction, or at the latest when the scene is built)."""
    with pytest.raises(InvalidParameterError) as exc_info:
        FetchSimulator(**kwargs).run("fetch", FetchAction(hold=0.0, air_hold=0.0))
    assert type(exc_info.value) is InvalidParameterError


# --------------------------------------------------------------------------------------------
# the estimators

GEOM = ClampGeometry(L=0.0385, theta_0=0.0)


@dataclass(frozen=True)
class Clamp:
    """A synthetic clamp-and-hold: SLS moment plus noise, sampled at ``fs``."""

    t: np.ndarray
    theta: np.ndarray
    M: np.ndarray
    geometry: ClampGeometry
    theta_1: float
    theta_d: float
    omega: float

    @property
    def t_d(self) -> float:
        return self.theta_d / self.omega


@st.composite
def clamps(draw: st.DrawFn) -> Clamp:
    """A random-but-valid relaxation trace (stiffness over three decades, noise to 2 %)."""
    k = math.exp(draw(st.floats(math.log(1e2), math.log(1e5))))
    params = SLSParams.from_prony(k, draw(st.floats(0.05, 0.9)), draw(st.floats(0.3, 10.0)))
    geometry = ClampGeometry(L=draw(st.floats(0.02, 0.06)), theta_0=draw(st.floats(0.0, 0.2)))
    theta_1 = draw(st.floats(0.0, 0.01))
    theta_d = theta_1 + draw(st.floats(0.005, 0.06))
    omega = draw(st.floats(0.01, 0.3))
    fs = draw(st.sampled_from([50.0, 100.0, 200.0]))
    hold = draw(st.floats(1.0, 15.0))
    t = np.arange(0.0, theta_d / omega + hold, 1.0 / fs)
    m = moment_trace(t, params, geometry, theta_1, theta_d, omega)
    noise = draw(st.sampled_from([0.0, 1e-4, 3e-3, 2e-2]))
    rng = np.random.default_rng(draw(st.integers(0, 2**16)))
    m = m + noise * float(np.max(np.abs(m))) * rng.standard_normal(t.size)
    return Clamp(t, clamp_angle(t, theta_d, omega), m, geometry, theta_1, theta_d, omega)


def quietly(call: Callable[[], Any]) -> Any:
    """Run ``call`` with numerical warnings silenced (the property is about exceptions)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return call()


def estimate_or_typed(call: Callable[[], Any], kind: type) -> Any:
    """``call()`` returns a ``kind`` or raises exactly EstimationError (None then)."""
    try:
        out = quietly(call)
    except EstimationError as exc:
        assert type(exc) is EstimationError
        return None
    assert isinstance(out, kind)
    return out


@examples(60)
@given(clamps())
def test_estimators_on_valid_clamps(c: Clamp) -> None:
    """On random-but-valid traces every viscoelastic estimator (the full fit also at the
    trace's known contact angle) returns an estimate (positive springs where it says it is
    reliable) or an EstimationError, nothing else."""
    for est in (
        estimate_or_typed(lambda: estimate_three_step(c.t, c.theta, c.M, c.geometry),
                          ViscoelasticEstimate),
        estimate_or_typed(lambda: estimate_full_fit(c.t, c.theta, c.M, c.geometry,
                                                    omega=c.omega, theta_d=c.theta_d,
                                                    clamp_weight=0.3),
                          ViscoelasticEstimate),
        estimate_or_typed(lambda: estimate_full_fit(c.t, c.theta, c.M, c.geometry,
                                                    omega=c.omega, theta_d=c.theta_d,
                                                    clamp_weight=0.3, theta_1=c.theta_1),
                          ViscoelasticEstimate),
    ):
        if est is not None and est.reliable:
            assert est.K1 > 0 and est.K2 > 0 and est.B > 0
    hold = estimate_or_typed(lambda: estimate_from_hold(
        c.t, c.M, c.geometry, c.theta_1, c.theta_d, c.omega, c.t_d, settle=0.1), HoldEstimate)
    if hold is not None:
        assert hold.K1 > 0 and 0 < hold.g1 < 1 and hold.tau1 > 0


@st.composite
def slides(draw: st.DrawFn) -> tuple[np.ndarray, ...]:
    """Random-but-valid contact forces of an induced slide: a ratio rising to ``mu`` with
    noise, normal forces that may drop out."""
    n = draw(st.integers(20, 600))
    t = np.cumsum(np.full(n, 1.0 / draw(st.sampled_from([50.0, 100.0, 500.0]))))
    mu = draw(st.floats(0.05, 1.0))
    rng = np.random.default_rng(draw(st.integers(0, 2**16)))
    noise = draw(st.sampled_from([0.0, 0.01, 0.1]))
    normal = draw(st.floats(0.0, 5.0)) * (1 + 0.1 * np.sin(t))
    ratio = mu * (1 - np.exp(-t / draw(st.floats(0.01, 1.0))))
    out = [t]
    for _ in range(2):
        nf = normal + noise * rng.standard_normal(n)
        out += [nf, ratio * nf + noise * mu * rng.standard_normal(n)]
    return tuple(out)


@examples(60)
@given(slides(), st.one_of(st.none(), st.integers(3, 40), st.integers(-2, 300)),
       st.floats(0.1, 10.0))
def test_friction_on_valid_slides(s: tuple[np.ndarray, ...], window: int | None,
                                  stability: float) -> None:
    """estimate_friction returns a FrictionEstimate or an EstimationError, nothing else."""
    est = estimate_or_typed(lambda: estimate_friction(*s, window=window, stability=stability),
                            FrictionEstimate)
    if est is not None:
        assert math.isfinite(est.mu) and est.mu >= 0


@st.composite
def finite_traces(draw: st.DrawFn) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Strictly increasing time and arbitrary finite samples (tiny, huge, subnormal): valid
    input as far as the documented checks go (samples past +-1e12 refused by them), but no
    clamp at all."""
    n = draw(st.integers(0, 80))
    steps = draw(st.lists(st.floats(1e-6, 10.0), min_size=n, max_size=n))
    t = np.cumsum([0.0, *steps])[:n]
    sample = st.one_of(st.floats(-1e3, 1e3), st.floats(-1.0, 1.0),
                       st.sampled_from([0.0, 1e300, -1e300, 1e-300, 5e-324]))
    theta = np.array(draw(st.lists(sample, min_size=n, max_size=n)), dtype=float)
    m = np.array(draw(st.lists(sample, min_size=n, max_size=n)), dtype=float)
    return t, theta, m


@examples(60)
@given(finite_traces(), st.one_of(st.none(), st.floats(1e-6, 10.0)),
       st.one_of(st.none(), st.floats(1e-6, 1.0)), st.floats(-1.0, 10.0), st.floats(0.0, 5.0))
def test_estimators_on_arbitrary_finite_traces(
        traces: tuple[np.ndarray, np.ndarray, np.ndarray], omega: float | None,
        theta_d: float | None, t_d: float, settle: float) -> None:
    """Traces that pass the input checks but hold no clamp: an estimate or an
    EstimationError, never an overflow, a LinAlgError or a solver's own exception."""
    t, theta, m = traces
    estimate_or_typed(lambda: estimate_three_step(t, theta, m, GEOM, omega, theta_d),
                      ViscoelasticEstimate)
    estimate_or_typed(lambda: estimate_full_fit(t, theta, m, GEOM, omega, theta_d),
                      ViscoelasticEstimate)
    estimate_or_typed(lambda: estimate_from_hold(t, m, GEOM, min(abs(t_d), 0.5), 0.6,
                                                 omega or 0.1, t_d, settle), HoldEstimate)
    estimate_or_typed(lambda: estimate_friction(t, theta, m, m, theta), FrictionEstimate)
    forces = {"normal_left": m, "tangential_left": theta, "normal_right": m,
              "tangential_right": theta}
    half = t >= (t[t.size // 2] if t.size else 0.0)
    estimate_or_typed(lambda: read_mu(t, forces, half, ~half), tuple)
    estimate_or_typed(lambda: read_mu(t, forces, half, None, "sum"), tuple)


BASE = np.arange(0.0, 3.0, 0.01)


@st.composite
def bad_traces(draw: st.DrawFn) -> tuple[str, np.ndarray | Any, np.ndarray | Any]:
    """A time vector and a trace with one documented defect: too short, NaN/inf, time not
    strictly increasing, mismatched lengths, not 1-D, or not numbers."""
    t, y = BASE.copy(), np.sin(BASE) + 2.0
    kind = draw(st.sampled_from(["short", "nonfinite", "unsorted", "repeated", "mismatch",
                                 "2d", "text", "complex", "empty"]))
    if kind == "short":
        k = draw(st.integers(0, 9))
        return kind, t[:k], y[:k]
    if kind == "nonfinite":
        i = draw(st.integers(0, t.size - 1))
        (t if draw(st.booleans()) else y)[i] = draw(st.sampled_from([math.nan, math.inf,
                                                                    -math.inf]))
        return kind, t, y
    if kind in ("unsorted", "repeated"):
        i = draw(st.integers(1, t.size - 1))
        t[i] = t[i - 1] - (draw(st.floats(1e-9, 1.0)) if kind == "unsorted" else 0.0)
        return kind, t, y
    if kind == "mismatch":
        k = draw(st.integers(1, 5))
        return kind, t, (y[:-k] if draw(st.booleans()) else np.r_[y, y[:k]])
    if kind == "2d":
        return kind, t, np.stack([y, y])
    if kind == "text":
        return kind, t, [str(v) for v in y]
    if kind == "complex":
        return kind, t, y + 0j
    return kind, np.array([]), np.array([])


@examples(150)
@given(bad_traces(), st.sampled_from(["three_step", "full_fit", "from_hold", "friction",
                                     "slip_level"]))
def test_estimators_refuse_bad_traces(bad: tuple[str, Any, Any], which: str) -> None:
    """Every documented trace defect is exactly an EstimationError, whichever estimator."""
    _, t, y = bad
    calls: dict[str, Callable[[], Any]] = {
        "three_step": lambda: estimate_three_step(t, y, y, GEOM),
        "full_fit": lambda: estimate_full_fit(t, y, y, GEOM),
        "from_hold": lambda: estimate_from_hold(t, y, GEOM, 0.001, 0.02, 0.1, 0.2),
        "friction": lambda: estimate_friction(t, y, y, y, y),
        "slip_level": lambda: read_mu(t, dict.fromkeys(SLIP_FORCES, y),
                                      np.ones(np.shape(t), dtype=bool), None),
    }
    with pytest.raises(EstimationError) as exc_info:
        quietly(calls[which])
    assert type(exc_info.value) is EstimationError


@examples(60)
@given(L=around(Range(0.0, 1.0, lo_open=True)),
       theta_0=st.one_of(around(Range(-math.pi / 2, math.pi / 2, lo_open=True, hi_open=True)),
                         st.sampled_from([math.nan, math.inf])))
def test_clamp_geometry_numbers(L: Any, theta_0: Any) -> None:
    """A lever arm in (0, 1] m and a theta_0 within (-pi/2, pi/2) make a geometry; anything
    else (NaN/inf too) is an EstimationError (wrong types: see below)."""
    assume(isinstance(L, int | float) and not isinstance(L, bool))
    assume(isinstance(theta_0, int | float) and not isinstance(theta_0, bool))
    if (Range(0.0, 1.0, lo_open=True).contains(L)
            and Range(-math.pi / 2, math.pi / 2, lo_open=True, hi_open=True).contains(theta_0)):
        assert ClampGeometry(L=L, theta_0=theta_0).L == L
    else:
        with pytest.raises(EstimationError) as exc_info:
            ClampGeometry(L=L, theta_0=theta_0)
        assert type(exc_info.value) is EstimationError


@examples(60)
@given(k=st.floats(1e-3, 1e7), g1=around(Range(0.0, 1.0, hi_open=True)),
       tau1=around(Range(0.0, None, lo_open=True)))
def test_prony_conversion_numbers(k: float, g1: Any, tau1: Any) -> None:
    """``SLSParams.from_prony``: g1 in [0, 1) and finite tau1 > 0 convert and back (g1 = 0 to
    an SLS without a Maxwell arm); other numbers are an EstimationError (wrong types: see
    below)."""
    assume(all(isinstance(v, int | float) and not isinstance(v, bool) for v in (g1, tau1)))
    if Range(0.0, 1.0, hi_open=True).contains(g1) and Range(0.0, None, True).contains(tau1):
        if g1 != 0 and g1 * k * tau1 == 0.0:  # K2 or B underflows to 0
            return
        p = SLSParams.from_prony(k, g1, tau1)
        assert p.g1 == pytest.approx(g1, abs=1e-12)
        if g1 > 0:
            assert p.tau1 == pytest.approx(tau1)
        else:
            assert (p.K1, p.K2, p.B) == (k, 0.0, 0.0)
    else:
        with pytest.raises(EstimationError) as exc_info:
            SLSParams.from_prony(k, g1, tau1)
        assert type(exc_info.value) is EstimationError


# Estimator inputs of the wrong type and edge cases of the SLS model (estimators/relaxation.py,
# friction.py and sls.py): each test is the property as documented, over explicit inputs.

C = Clamp(BASE, clamp_angle(BASE, 0.02, 0.1),
          moment_trace(BASE, SLSParams.from_prony(5e3, 0.4, 1.0), GEOM, 0.001, 0.02, 0.1),
          GEOM, 0.001, 0.02, 0.1)
HOLD_ARGS = {"theta_1": C.theta_1, "theta_d": C.theta_d, "omega": C.omega, "t_d": C.t_d,
             "settle": 0.0}


@pytest.mark.parametrize(("fn", "name", "value"), [
    ("three_step", "omega", "0.1"), ("three_step", "theta_d", 0.1j),
    ("full_fit", "clamp_weight", "0.1"), ("from_hold", "theta_1", "0.1"),
    ("from_hold", "t_d", None)])
def test_viscoelastic_estimators_refuse_wrong_scalar_types(fn: str, name: str,
                                                           value: Any) -> None:
    """A non-number option is an EstimationError naming it."""
    calls: dict[str, Callable[[], Any]] = {
        "three_step": lambda: estimate_three_step(C.t, C.theta, C.M, GEOM, **{name: value}),
        "full_fit": lambda: estimate_full_fit(C.t, C.theta, C.M, GEOM, **{name: value}),
        "from_hold": lambda: estimate_from_hold(C.t, C.M, GEOM, **(HOLD_ARGS | {name: value})),
    }
    with pytest.raises(EstimationError) as exc_info:
        quietly(calls[fn])
    refused(exc_info, EstimationError, name)


@pytest.mark.parametrize("window", [math.nan, math.inf, "a"])
def test_friction_window_must_be_an_integer(window: Any) -> None:
    """A rolling window that is not an integer is an EstimationError naming it."""
    t = np.arange(0.0, 2.0, 0.01)
    f = np.ones_like(t)
    with pytest.raises(EstimationError) as exc_info:
        quietly(lambda: estimate_friction(t, f, 0.3 * f, f, 0.3 * f, window=window))
    refused(exc_info, EstimationError, "window")


@pytest.mark.parametrize("which", ["ClampGeometry", "SLSParams", "from_prony"])
def test_sls_constructors_refuse_wrong_types(which: str) -> None:
    """A non-number geometry or SLS parameter is an EstimationError."""
    calls: dict[str, Callable[[], Any]] = {
        "ClampGeometry": lambda: ClampGeometry(L="0.04", theta_0=0.0),  # type: ignore[arg-type]
        "SLSParams": lambda: SLSParams(K1="1", K2=1.0, B=1.0),  # type: ignore[arg-type]
        "from_prony": lambda: SLSParams.from_prony(1.0, "0.4", 1.0),  # type: ignore[arg-type]
    }
    with pytest.raises(EstimationError) as exc_info:
        calls[which]()
    assert type(exc_info.value) is EstimationError


def test_sls_params_with_zero_springs() -> None:
    """Every accepted SLSParams converts to Prony terms (or the constructor refuses it)."""
    try:
        p = SLSParams(K1=0.0, K2=0.0, B=1.0)
    except EstimationError:
        return
    g1, tau1 = p.to_prony()
    assert 0.0 <= g1 < 1.0 and tau1 > 0


@pytest.mark.parametrize("which", ["steady_moment theta_1=nan", "moment_trace t_start=nan",
                                   "moment_trace n_sub=0"])
def test_sls_forward_model_refuses_bad_input(which: str) -> None:
    """The forward model returns finite, non-zero moments past contact or raises
    EstimationError."""
    p = SLSParams(1e3, 1e3, 1e3)
    g = ClampGeometry(0.04, 0.0)
    t = np.array([0.0, 0.1, 1.0])
    calls: dict[str, Callable[[], Any]] = {
        "steady_moment theta_1=nan": lambda: steady_moment(p, g, math.nan, 0.02),
        "moment_trace t_start=nan": lambda: moment_trace(t, p, g, 0.001, 0.02, 0.1,
                                                         t_start=math.nan),
        "moment_trace n_sub=0": lambda: moment_trace(t, p, g, 0.001, 0.02, 0.1,
                                                     method="quadrature", n_sub=0),
    }
    try:
        out = quietly(calls[which])
    except EstimationError:
        return
    assert np.all(np.isfinite(out)) and np.any(np.asarray(out) != 0), out


def test_prony_without_relaxation() -> None:
    """g1 = 0 (a purely elastic food, in the documented range) converts to an SLS without a
    Maxwell arm, whose moment is the spring's alone: no relaxation in the hold, every
    forward-model method agreeing with eq. 6's relaxed moment."""
    p = SLSParams.from_prony(1e3, 0.0, 1.0)
    assert p.K1 == 1e3 and p.K2 == 0.0
    assert p.to_prony() == (0.0, math.inf)
    m_inf = steady_moment(p, GEOM, 0.001, 0.02)
    t = np.array([0.0, 0.1, 0.3, 1.0, 5.0])
    for method in ("closed", "quadrature", "ivp"):
        m = moment_trace(t, p, GEOM, 0.001, 0.02, 0.1, method=method)
        assert m[0] == 0.0 and 0.0 < m[1] < m_inf, (method, m)
        np.testing.assert_allclose(m[2:], m_inf, rtol=1e-9, err_msg=method)
