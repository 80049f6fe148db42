"""Builds a compiled scene: the base MJCF asset plus one deformable flex per food piece.

The fixed parts (plate, end-effector, sensors) live in ``assets/fetch_base.xml``; this module
varies them through :class:`mujoco.MjSpec` (stage height, blade length, plate friction) and
adds the pieces, then looks every id up by name.
"""

from __future__ import annotations

import ctypes
import math
import warnings
from dataclasses import asdict, dataclass, field
from importlib import resources
from typing import Any

import mujoco
import numpy as np

from fetch_env import clipping
from fetch_env.clipping import ClipRecord
from fetch_env.errors import InvalidParameterError, require, require_finite, require_pieces
from fetch_env.layouts import Piece, check_no_overlap

BASE_XML = "fetch_base.xml"
# Vertices per axis of each piece's collision/strain mesh.  All pieces use one trilinear cell
# (24 dofs); the mesh only shapes the surface and spreads the contact.  MuJoCo makes one
# contact per mesh tetrahedron and geom, so a cube of 2 x 2 x 2 vertices (6 tetrahedra)
# touches a blade at one or two jumping points and chatters (moment noise ~80 % of the mean
# in a firm clamp); 3 x 3 x 3 (48 tetrahedra) spreads it over a face (~1.5 %) at ~30 % cost.
MESH_COUNT = {"cube": 3, "ellipsoid": 4, "sphere": 4}
# Largest E dt^2 / (rho s^2) (s: the piece's thinnest extent; the flex's stiffness-to-mass
# ratio per step) simulated at the material's modulus.  Above it MuJoCo's effective-metric
# (M + dt^2 K) step is ill-conditioned: small 200 MPa dice (1e5) blew up in diced mixes
# (LE 9, divergence) without the cap and ran cleanly with it.  Such pieces get the capped
# modulus instead (reported per piece as ``young_simulated``): still > 40x stiffer than the
# soft foods and held by a motor that stalls at 2 N m, they deform < 1 % in any clamp.
CONDITIONING_LIMIT = 1e4
# Friction impratio of scenes with more than one piece (the base scene's 1000 stays for one
# piece: every physics test, every probe, the Block env).  impratio makes MuJoCo's soft
# friction nearly Coulomb: a held contact creeps at a speed ~ 1 / impratio.  It also sets how
# much of each held contact's cone the Newton solve must refold every iteration, and a diced
# fetch's ~240 held contacts made that most of its cost.  Measured over 40 diced mixes
# (benchmarks/bench_step_size.py --steps 0.0025,0.005,0.005 --impratios 1000,1000,100):
# at 100 the pieces end fetched-or-not as at 2.5 ms and 1000 in 91.8 % of cases, against
# 92.4 % at 1000 and a 93 % chaos floor (the same run with every piece moved 1 nm), the
# fetch rate moves +0.03 +- 0.03, and the mixes run 1.3x faster in all.  The middle of three
# cubes in a row, held only by its neighbours' friction, sags over a 1 s air hold within
# 10 um of its sag at 1000 (tests/test_fetch.py).  At 30 one mix in 40 under-converged
# MuJoCo's M+K solve (docs/validation/impratio.md).
MULTI_PIECE_IMPRATIO = 100.0
BASE_TIMESTEP = 0.005  # [s] the base scene's physics step (assets/fetch_base.xml)
MIN_CONTACT_TIMECONST = 0.001  # [s] the stiffest contact Geometry allows (stable at the 5 ms step)
# [s] the stiffest blade-food contact a probe may ask for (build_scene's
# piece_contact_timeconst), stable at a 1 ms step: below the precise relaxation probe's for
# the stiffest soft food (~44 us for a 5 MPa piece 4.8 mm thin; ProbeConfig.
# relaxation_contact_ratio), the floor of stiffer ones
MIN_PIECE_CONTACT_TIMECONST = 2e-5
# Vertices per axis of a cube's contact mesh under such a stiff contact (build_scene's
# cube_mesh_count): on the 3 x 3 x 3 mesh a cube's flat face, pressed by a tilted blade,
# chatters (a 15 mm, 2 MPa cube's held moment swung between 0.35 and 1.2 N m); on 5 x 5 x 5
# the load spreads over the face.  One precise clamp, uncalibrated, on 64 tuning cubes:
# tau1 within 0.56 / 7.2 % (median / 90th percentile), against 4.5 / 28 % on 3 x 3 x 3;
# 4 x 4 x 4 left one of 64 unidentified.
STIFF_CONTACT_CUBE_MESH = 5
BLADE_HALF_THICKNESS = 0.002  # [m] thick enough that no food vertex can reach the far side

# MuJoCo's process-wide asset cache makes the compiled flex stiffness and node masses depend,
# in their last bits, on what was built before in the process (measured: 396 values differ
# for a sphere compiled cold against after three other scenes; and a diced mix's node masses
# differ between the first build in a process and every later one, when the cache was only
# switched off just before compiling).  Those bits grow into different trajectories (a diced
# fetch that diverged after another scene ran cleanly on its own).  Switched off at import,
# before any spec exists, every compile is a function of its input only; our scenes have no
# large meshes for it to save time on.  tests/test_fetch.py checks cold against warm builds.
mujoco.mj_setCacheCapacity(mujoco.mj_getCache(), 0)


@dataclass(frozen=True)
class Geometry:
    """End-effector geometry and the approach pose [m, rad].

    Attributes:
        blade_length: hinge axis to blade tip [m].  45 mm puts the hinge about 38 mm above a
            15 mm piece's centroid, so the study's angles mean the study's squeeze: with the
            1 mm gap, LE stays under 0.1 at 0.045 rad and passes 0.38 at 0.09 rad.
        blade_width: blade extent along the hinge axis (x) [m].
        tip_clearance: blade tip above the plate with the blades vertical (closed) [m].
        gap: clearance between each blade's inner face and the food's outer side at the open
            pose [m]; the faces' offset from the hinge axis is set from it per scene.
        contact_timeconst: time constant of every contact's constraint [s] (MuJoCo's
            ``solref``, damping ratio 1).  Not a length, but a property of the blade-food
            interface the robot sees: MuJoCo's contact is a spring in series with the food
            whose stiffness grows as ``1 / timeconst**2``.  At the default 10 ms (twice the 5 ms
            step, the least a positive ``solref`` is safe at) it is stiff against soft foods
            but not against stiff ones: a 3.9 MPa, 10 mm sphere's moment relaxes to 0.86
            of its hold start where the material law gives 0.70.  Below twice the step it
            is given to MuJoCo as direct stiffness ``1 / tc**2`` and damping ``2 / tc``
            (the same spring, which MuJoCo's ``refsafe`` leaves as authored; see
            :func:`contact_solref`).  The relaxation experiment
            stiffens it further with the food
            (:func:`fetch_env.controller.relaxation_contact_timeconst`: 1.9 ms for that
            sphere, which then relaxes to 0.74); the fetch and the slip use this value.
    """

    blade_length: float = 0.045
    blade_width: float = 0.048
    tip_clearance: float = 0.001
    gap: float = 0.001
    contact_timeconst: float = 0.01

    def __post_init__(self) -> None:
        for key in ("blade_length", "blade_width", "tip_clearance", "gap", "contact_timeconst"):
            require_finite(key, getattr(self, key))
        require(0.03 <= self.blade_length <= 0.2, "blade_length", self.blade_length,
                "in [0.03, 0.2] m")
        require(0.01 <= self.blade_width <= 0.1, "blade_width", self.blade_width,
                "in [0.01, 0.1] m")
        require(0 <= self.tip_clearance <= 0.02, "tip_clearance", self.tip_clearance,
                "in [0, 0.02] m")
        require(0 <= self.gap <= 0.01, "gap", self.gap, "in [0, 0.01] m")
        require(MIN_CONTACT_TIMECONST <= self.contact_timeconst <= 0.1, "contact_timeconst",
                self.contact_timeconst, f"in [{MIN_CONTACT_TIMECONST}, 0.1] s")

    @property
    def hinge_height(self) -> float:
        """Height of the hinge axis above the plate [m]."""
        return self.tip_clearance + self.blade_length


@dataclass(frozen=True)
class PoseInfo:
    """Where the clamp starts, in the study's terms.

    Each half-spoon's inner (contact) face is parallel to the hinge axis and offset from it
    by ``face_offset``, like the inside of a spoon's bowl, so that at the open pose the faces
    are vertical, parallel to the food's sides and ``gap`` away from them.  ``theta`` is the
    study's hinge angle: 0 at the open pose, growing as the blades close (tilting inward).

    Attributes:
        L: distance from the hinge axis down to the pieces' centroid height (the
            equivalent contact section) [m].
        theta_0: the angle the study's equations 2-7 call theta_0, at which the contact face
            is vertical: 0 here, the open pose, so the face tilts by theta - theta_0 = theta.
        theta_open: the open pose, 0 by definition of theta.
        theta_closed: the angle at which the two faces meet at the tips (fully closed).
        face_offset: distance from the hinge axis to each contact face [m].
        stage_xy: where the stage (hinge axis) sits over the plate [m].
        hinge_height: hinge axis above the plate [m].
    """

    L: float
    theta_0: float
    theta_open: float
    theta_closed: float
    face_offset: float
    stage_xy: tuple[float, float]
    hinge_height: float

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)

    def face_y(self, theta: float, depth: float) -> float:
        """Distance from the hinge plane to a contact face at ``depth`` below the axis [m]."""
        return self.face_offset / math.cos(theta) - depth * math.tan(theta)


@dataclass
class Scene:
    """A compiled scene and the ids the simulator needs (all looked up by name)."""

    model: mujoco.MjModel
    pieces: tuple[Piece, ...]
    geometry: Geometry
    pose: PoseInfo
    ids: dict[str, int] = field(default_factory=dict)
    piece_flex: list[int] = field(default_factory=list)
    # a probe's own contact settings (build_scene), None where the geometry's hold
    piece_contact_timeconst: float | None = None
    cube_mesh_count: int | None = None

    @property
    def robot_nv(self) -> int:
        """Degrees of freedom that are not food nodes (the stage and the hinges): while
        every piece sleeps, ``MjData.nv_awake`` equals this."""
        m = self.model
        return int(m.nv - sum(3 * m.flex_nodenum[f] for f in self.piece_flex))

    def describe(self) -> dict[str, Any]:
        """A JSON-able description that rebuilds the same scene (with a probe's own contact
        settings where it has them)."""
        out = {"pieces": [p.to_dict() for p in self.pieces],
               "geometry": asdict(self.geometry), "pose": self.pose.to_dict()}
        for key in ("piece_contact_timeconst", "cube_mesh_count"):
            if getattr(self, key) is not None:
                out[key] = getattr(self, key)
        return out


def _face_offset(pieces: tuple[Piece, ...], geometry: Geometry, stage_y: float) -> float:
    """Offset of the vertical contact faces from the hinge plane: the pieces' widest reach
    along the clamp direction (their support function, exact for boxes and ellipsoids) on
    either side of the stage, plus ``geometry.gap``."""
    reach = max(max(p.support(np.array([0.0, side, 0.0])) - side * stage_y for p in pieces)
                for side in (-1.0, 1.0))
    return float(reach + geometry.gap)


def release_freed_memory() -> None:
    """Hand the C heap's free pages back to the system (glibc's ``malloc_trim``; elsewhere
    nothing).

    A compiled scene holds MuJoCo's model, a diced mix's many megabytes in many blocks; the
    environments keep their last 8 scenes and free older ones, but glibc keeps freed heap
    pages for reuse, and models of varying size reuse them badly: a process's resident memory
    grew with the number of scenes it had compiled (+73 MiB over 300 Diced episodes, 254 ->
    435 MiB, no object leaking: with the pages handed back after every episode it stayed at
    143-144 MiB; ``benchmarks/soak.py --malloc-trim``).  Called before each compile, at
    ~0.3 ms a call (a Block episode compiles 3 scenes in ~300 ms).
    """
    global _LIBC
    if _LIBC is None:
        try:
            _LIBC = ctypes.CDLL("libc.so.6").malloc_trim
        except (OSError, AttributeError):  # not glibc: nothing to trim
            _LIBC = False
    if _LIBC:
        _LIBC(0)


_LIBC: Any = None  # glibc's malloc_trim once looked up (False: none)


def build_scene(pieces: tuple[Piece, ...] | list[Piece], geometry: Geometry | None = None,
                timestep: float | None = None, impratio: float | None = None,
                piece_contact_timeconst: float | None = None,
                cube_mesh_count: int | None = None) -> Scene:
    """Compile the base scene with ``pieces`` on the plate and the end-effector above them.

    ``timestep`` and ``impratio`` override the base scene's (5 ms; impratio 1000 for one
    piece, :data:`MULTI_PIECE_IMPRATIO` for several).  ``piece_contact_timeconst`` (a probe's
    instrument setting, down to :data:`MIN_PIECE_CONTACT_TIMECONST`) gives the pieces' own
    contact that time constant, and so the blades' contact with them (the food's priority
    sets it), while the plate's stays ``geometry.contact_timeconst``: a stiff plate contact
    launches a resting piece.  ``cube_mesh_count`` replaces a cube's contact mesh's vertices
    per axis (:data:`MESH_COUNT`; :data:`STIFF_CONTACT_CUBE_MESH` under a stiff contact).
    Validates everything first (pieces, overlaps, geometry) so that nothing is compiled for
    bad input.
    """
    require(isinstance(pieces, tuple | list) and len(pieces) > 0, "pieces", pieces,
            "a non-empty sequence of Piece")
    require(geometry is None or isinstance(geometry, Geometry), "geometry", geometry,
            "a Geometry or None")
    for name, value, lo, hi in (("timestep", timestep, 1e-4, 0.02),
                                ("impratio", impratio, 1.0, 1e4),
                                ("piece_contact_timeconst", piece_contact_timeconst,
                                 MIN_PIECE_CONTACT_TIMECONST, 0.1)):
        if value is not None:
            require_finite(name, value)
            require(lo <= value <= hi, name, value, f"in [{lo:g}, {hi:g}]")
    require(cube_mesh_count is None
            or (isinstance(cube_mesh_count, int) and not isinstance(cube_mesh_count, bool)
                and 2 <= cube_mesh_count <= 8),
            "cube_mesh_count", cube_mesh_count, "an integer in [2, 8] or None")
    pieces = tuple(pieces)
    geometry = geometry or Geometry()
    stage_xy = _check_pieces_fit(pieces, geometry)
    pose = _clamp_pose(pieces, geometry, stage_xy)
    mujoco.mj_setCacheCapacity(mujoco.mj_getCache(), 0)  # again, in case a caller re-enabled it
    release_freed_memory()  # the scenes freed since the last compile (a long run's RSS)
    spec = _base_spec(pieces, geometry, pose, timestep, impratio)
    # The conditioning cap is no secret: warn (the env and the CLI report it themselves).
    clipping.warn(young_caps(pieces, spec.option.timestep))
    solref = contact_solref(geometry.contact_timeconst, spec.option.timestep)
    for geom in spec.geoms:
        geom.solref = solref
    plate = spec.geom("plate")
    plate.friction = [pieces[0].material.plate_mu, 0.005, 0.0001]
    piece_solref = (solref if piece_contact_timeconst is None
                    else contact_solref(piece_contact_timeconst, spec.option.timestep))
    counts = dict(MESH_COUNT, **({} if cube_mesh_count is None else {"cube": cube_mesh_count}))
    for i, p in enumerate(pieces):
        _add_piece(spec, i, p, piece_solref, counts[p.shape])
    with warnings.catch_warnings():
        # MuJoCo warns that a trilinear flex "has no equality constraints or passive forces"
        # although its elasticity is active (checked in tests/test_viscoelastic.py).
        warnings.filterwarnings("ignore", message=".*no equality constraints or passive")
        model = spec.compile()
    scene = Scene(model=model, pieces=pieces, geometry=geometry, pose=pose,
                  piece_contact_timeconst=piece_contact_timeconst,
                  cube_mesh_count=cube_mesh_count)
    _look_up_ids(scene)
    return scene


def _check_pieces_fit(pieces: tuple[Piece, ...], geometry: Geometry) -> tuple[float, float]:
    """Refuse pieces that are not ``Piece``, overlap, or do not fit between and under the
    blades; returns the stage's (x, y) over the plate: the middle of the pieces' extent."""
    for i, p in enumerate(pieces):
        require(isinstance(p, Piece), f"pieces[{i}]", p, "a Piece")
    check_no_overlap(pieces)
    xs = [p.x - p.extents[0] / 2 for p in pieces] + [p.x + p.extents[0] / 2 for p in pieces]
    ys = [p.y - p.extents[1] / 2 for p in pieces] + [p.y + p.extents[1] / 2 for p in pieces]
    stage_xy = ((min(xs) + max(xs)) / 2, (min(ys) + max(ys)) / 2)
    if max(xs) - min(xs) > geometry.blade_width + 0.02:
        raise InvalidParameterError(
            f"pieces span {max(xs) - min(xs):.4f} m across the blades, wider than "
            f"blade_width={geometry.blade_width} m + 20 mm")
    tallest = max(p.extents[2] for p in pieces)
    if tallest > geometry.hinge_height - 0.005:
        raise InvalidParameterError(
            f"pieces are {tallest:.4f} m tall, too tall for the end-effector: the hinge is "
            f"{geometry.hinge_height:.4f} m above the plate (blade_length + tip_clearance)")
    return stage_xy


def _clamp_pose(pieces: tuple[Piece, ...], geometry: Geometry,
                stage_xy: tuple[float, float]) -> PoseInfo:
    """The open pose over ``pieces``: faces ``geometry.gap`` from their sides, ``L`` down to
    their mass-weighted centroid height."""
    offset = _face_offset(pieces, geometry, stage_xy[1])
    masses = np.array([p.mass for p in pieces])
    z_centroid = float(masses @ np.array([p.centre[2] for p in pieces]) / masses.sum())
    return PoseInfo(L=geometry.hinge_height - z_centroid, theta_0=0.0, theta_open=0.0,
                    theta_closed=math.atan2(offset, geometry.blade_length), face_offset=offset,
                    stage_xy=stage_xy, hinge_height=geometry.hinge_height)


def _base_spec(pieces: tuple[Piece, ...], geometry: Geometry, pose: PoseInfo,
               timestep: float | None, impratio: float | None) -> mujoco.MjSpec:
    """The base MJCF with its options set and the stage and blades placed and sized."""
    xml = resources.files("fetch_env").joinpath("assets", BASE_XML).read_text()
    spec = mujoco.MjSpec.from_string(xml)
    if timestep is not None:
        spec.option.timestep = timestep
    if impratio is not None:
        spec.option.impratio = impratio
    elif len(pieces) > 1:
        spec.option.impratio = MULTI_PIECE_IMPRATIO
    stage = spec.body("stage")
    stage.pos = [pose.stage_xy[0], pose.stage_xy[1], geometry.hinge_height]
    offset = pose.face_offset
    for side, sign in (("left", -1.0), ("right", 1.0)):
        blade = spec.geom(f"blade_{side}")
        blade.size = [geometry.blade_width / 2, BLADE_HALF_THICKNESS, geometry.blade_length / 2]
        blade.pos = [0.0, sign * (offset + BLADE_HALF_THICKNESS), -geometry.blade_length / 2]
    if len(pieces) > 1:
        # MuJoCo's sleeping islands take pieces resting on the plate, untouched, out of the
        # pipeline (their plate contacts are most of a diced mix's constraints) until a blade
        # or another piece touches them; the stage is actuated, so it and whatever it holds
        # never sleep.  A lone piece is always the one being clamped, so there is nothing to
        # save, and single-piece scenes (every physics test and every probe) keep the exact
        # trajectories they were validated with: a piece that slept meets the blade with a
        # different first-contact transient, and a clamp near the slip limit can end
        # differently (measured: a 0.045 rad fetch of the default cube).
        spec.option.enableflags |= int(mujoco.mjtEnableBit.mjENBL_SLEEP)
    return spec


def _add_piece(spec: mujoco.MjSpec, i: int, p: Piece, solref: list[float], count: int) -> None:
    """Add piece ``i`` as a trilinear flex (one cell) with its material and contact settings,
    its contact mesh ``count`` vertices per axis."""
    body = spec.worldbody.add_body(name=f"piece_{i}", pos=p.centre.tolist())
    ext = p.extents
    flex = body.make_flex(
        f"piece_{i}", type="grid" if p.shape == "cube" else "ellipsoid", dim=3,
        dof="trilinear", count=[count] * 3, spacing=(ext / (count - 1)).tolist(),
        radius=0.0, mass=p.mass)
    mat = p.material
    flex.young = simulated_young(p, spec.option.timestep)
    flex.poisson = mat.poisson
    if mat.yield_strain > 0:
        flex.stressyield = [mat.yield_strain, 0.0]
    # priority 1 > blades (0): food-spoon contacts take this coefficient, exactly mu.
    flex.friction = [mat.mu, 0.005, 0.0001]
    flex.priority = 1
    flex.contype = 1
    flex.conaffinity = 7
    flex.condim = 3
    flex.selfcollide = mujoco.mjtFlexSelf.mjFLEXSELF_NONE
    flex.solref = solref
    flex.solimp = [0.9999, 0.9999, 0.001, 0.5, 2.0]
    flex.rgba = _colour(mat.young)


def _look_up_ids(scene: Scene) -> None:
    """Fill ``scene.ids`` and ``scene.piece_flex`` by name from the compiled model."""
    model = scene.model
    for kind, names in ((mujoco.mjtObj.mjOBJ_JOINT, ("hinge_left", "hinge_right", "lift")),
                        (mujoco.mjtObj.mjOBJ_ACTUATOR, ("servo_left", "servo_right",
                                                        "servo_lift")),
                        (mujoco.mjtObj.mjOBJ_GEOM, ("blade_left", "blade_right", "plate")),
                        (mujoco.mjtObj.mjOBJ_BODY, ("stage", "wrist"))):
        for name in names:
            scene.ids[name] = mujoco.mj_name2id(model, kind, name)
    scene.piece_flex = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_FLEX, f"piece_{i}")
                        for i in range(len(scene.pieces))]


def contact_solref(timeconst: float, timestep: float) -> list[float]:
    """MuJoCo ``solref`` for a contact time constant (damping ratio 1).

    MuJoCo's ``refsafe`` does not honour a time constant the step cannot resolve (under the
    standard integrators below twice the step; under ``discrete``, ours, a contact row with
    ``timeconst * dampratio`` below the step is replaced by the stiffest zero-restitution row
    for the step); below twice the step the same spring-damper is therefore given directly,
    stiffness ``1 / tc**2`` and damping ``2 / tc`` (MuJoCo's own conversion), which
    ``refsafe`` leaves as authored (measured: identical probe estimates with it disabled).
    Even so, the contact's compliance under ``discrete`` grows with the step
    (``docs/validation/probes.md``).
    """
    for name, value in (("timeconst", timeconst), ("timestep", timestep)):
        require_finite(name, value)
        require(value > 0, name, value, "> 0 s")
    if timeconst >= 2 * timestep:
        return [timeconst, 1.0]
    return [-1.0 / timeconst**2, -2.0 / timeconst]


def simulated_young(piece: Piece, timestep: float) -> float:
    """The modulus given to MuJoCo: the material's, capped at :data:`CONDITIONING_LIMIT`."""
    require(isinstance(piece, Piece), "piece", piece, "a Piece")
    require_finite("timestep", timestep)
    require(timestep > 0, "timestep", timestep, "> 0 s")
    thinnest = float(min(piece.extents))
    cap = CONDITIONING_LIMIT * piece.material.density * thinnest**2 / timestep**2
    return float(min(piece.material.young, cap))


def young_caps(pieces: tuple[Piece, ...] | list[Piece], timestep: float, first: int = 0,
               where: str = "") -> list[ClipRecord]:
    """A :mod:`fetch_env.clipping` record for each piece whose modulus
    :func:`simulated_young` caps at ``timestep`` (none for the others); the pieces are
    named ``pieces[first + i]``, and ``where`` (e.g. "in the slip probe") ends the reason."""
    require_pieces("pieces", pieces)
    out = []
    for i, p in enumerate(pieces):
        used = simulated_young(p, timestep)
        if used < p.material.young:
            out.append(clipping.record(
                "young", f"pieces[{first + i}].young", p.material.young, used,
                f"MuJoCo's conditioning limit 1e4 rho s^2 / dt^2 for this {p.size * 1e3:g} mm "
                f"{p.shape} at a {timestep * 1e3:g} ms step{where}; a piece that stiff deforms "
                "< 1 % in any clamp"))
    return out


def _colour(young: float) -> list[float]:
    """Soft foods warm and pale, hard foods dark: log-scaled over the study's range."""
    s = float(np.clip((math.log10(young) - 4) / (8.3 - 4), 0, 1))
    return [0.95 - 0.45 * s, 0.75 - 0.35 * s, 0.35 + 0.1 * s, 1.0]


def initial_state(scene: Scene) -> mujoco.MjData:
    """MjData at the open pose (hinges at 0, faces vertical), servos holding them there."""
    require(isinstance(scene, Scene), "scene", scene, "a Scene (build_scene)")
    m = scene.model
    d = mujoco.MjData(m)
    for side in ("left", "right"):
        d.qpos[m.jnt_qposadr[scene.ids[f"hinge_{side}"]]] = scene.pose.theta_open
        d.ctrl[scene.ids[f"servo_{side}"]] = scene.pose.theta_open
    mujoco.mj_forward(m, d)
    return d
