"""Builds a compiled scene: the base MJCF asset plus one deformable flex per food piece.

The fixed parts (plate, end-effector, sensors) live in ``assets/fetch_base.xml``; this module
varies them through :class:`mujoco.MjSpec` (stage height, blade length, plate friction) and
adds the pieces, then looks every id up by name.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import asdict, dataclass, field
from importlib import resources
from typing import Any

import mujoco
import numpy as np
from scipy.optimize import brentq

from fetch_env.errors import InvalidParameterError, require, require_finite
from fetch_env.layouts import Piece, check_no_overlap

BASE_XML = "fetch_base.xml"
# Vertices per axis of each piece's collision/strain mesh.  All pieces use one trilinear cell
# (24 dofs); the mesh only shapes the surface, and contacts dominate the cost.
MESH_COUNT = {"cube": 2, "ellipsoid": 4, "sphere": 4}


@dataclass(frozen=True)
class Geometry:
    """End-effector geometry and the approach pose [m, rad].

    Attributes:
        blade_length: hinge axis to blade tip [m].
        blade_width: blade extent along the hinge axis (x) [m].
        tip_clearance: blade tip above the plate with the blades vertical (closed) [m].
        gap: clearance between each blade's inner face and the food's outer side at the open
            pose [m]; the open angle is solved from it per scene.
    """

    blade_length: float = 0.06
    blade_width: float = 0.048
    tip_clearance: float = 0.001
    gap: float = 0.001

    def __post_init__(self) -> None:
        for key in ("blade_length", "blade_width", "tip_clearance", "gap"):
            require_finite(key, getattr(self, key))
        require(0.03 <= self.blade_length <= 0.2, "blade_length", self.blade_length,
                "in [0.03, 0.2] m")
        require(0.01 <= self.blade_width <= 0.1, "blade_width", self.blade_width,
                "in [0.01, 0.1] m")
        require(0 <= self.tip_clearance <= 0.02, "tip_clearance", self.tip_clearance,
                "in [0, 0.02] m")
        require(0 <= self.gap <= 0.01, "gap", self.gap, "in [0, 0.01] m")

    @property
    def hinge_height(self) -> float:
        """Height of the hinge axis above the plate [m]."""
        return self.tip_clearance + self.blade_length


@dataclass(frozen=True)
class PoseInfo:
    """Where the clamp starts, in the study's terms.

    ``theta`` is the study's hinge angle: 0 at the open pose, growing as the blades close,
    ``theta_0`` at the closed pose.  ``L`` is the distance from the hinge axis down to the
    height of the pieces' centroid (the equivalent contact section).
    """

    L: float
    theta_0: float
    theta_open: float
    stage_xy: tuple[float, float]
    hinge_height: float

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


@dataclass
class Scene:
    """A compiled scene and the ids the simulator needs (all looked up by name)."""

    model: mujoco.MjModel
    pieces: tuple[Piece, ...]
    geometry: Geometry
    pose: PoseInfo
    ids: dict[str, int] = field(default_factory=dict)
    piece_flex: list[int] = field(default_factory=list)

    def describe(self) -> dict[str, Any]:
        """A JSON-able description that rebuilds the same scene."""
        return {"pieces": [p.to_dict() for p in self.pieces],
                "geometry": asdict(self.geometry), "pose": self.pose.to_dict()}


def _open_angle(pieces: tuple[Piece, ...], geometry: Geometry, stage_y: float) -> float:
    """Blade angle from vertical at which each blade clears every piece by ``geometry.gap``.

    A blade's inner face is the plane through the hinge axis; with the blade at angle phi
    from vertical, its outward normal is (0, +-cos phi, sin phi).  The clearance to the food
    is the plane offset minus the food's support function along that normal (exact for
    boxes and ellipsoids), and it grows monotonically with phi.
    """
    axis = np.array([0.0, stage_y, geometry.hinge_height])
    phis = []
    for side in (-1.0, 1.0):
        def clearance(phi: float, side: float = side) -> float:
            n = np.array([0.0, side * math.cos(phi), math.sin(phi)])
            return float(axis @ n - max(p.support(n) for p in pieces)) - geometry.gap
        if clearance(0.0) >= 0:
            phis.append(0.0)
            continue
        if clearance(1.2) < 0:
            raise InvalidParameterError(
                "pieces are too wide or too tall for the end-effector: no open pose clears "
                f"them by gap={geometry.gap} m (blade_length={geometry.blade_length} m)")
        phis.append(brentq(clearance, 0.0, 1.2, xtol=1e-12))
    return max(phis)


def build_scene(pieces: tuple[Piece, ...] | list[Piece], geometry: Geometry | None = None,
                timestep: float | None = None) -> Scene:
    """Compile the base scene with ``pieces`` on the plate and the end-effector above them.

    Validates everything first (pieces, overlaps, geometry) so that nothing is compiled for
    bad input.
    """
    pieces = tuple(pieces)
    geometry = geometry or Geometry()
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
    phi_open = _open_angle(pieces, geometry, stage_xy[1])
    masses = np.array([p.mass for p in pieces])
    z_centroid = float(masses @ np.array([p.centre[2] for p in pieces]) / masses.sum())
    pose = PoseInfo(L=geometry.hinge_height - z_centroid, theta_0=phi_open,
                    theta_open=phi_open, stage_xy=stage_xy,
                    hinge_height=geometry.hinge_height)

    xml = resources.files("fetch_env").joinpath("assets", BASE_XML).read_text()
    spec = mujoco.MjSpec.from_string(xml)
    if timestep is not None:
        spec.option.timestep = timestep
    stage = spec.body("stage")
    stage.pos = [stage_xy[0], stage_xy[1], geometry.hinge_height]
    for side, sign in (("left", -1.0), ("right", 1.0)):
        blade = spec.geom(f"blade_{side}")
        blade.size = [geometry.blade_width / 2, 0.001, geometry.blade_length / 2]
        blade.pos = [0.0, sign * 0.001, -geometry.blade_length / 2]
    plate = spec.geom("plate")
    plate.friction = [pieces[0].material.plate_mu, 0.005, 0.0001]

    for i, p in enumerate(pieces):
        body = spec.worldbody.add_body(name=f"piece_{i}", pos=p.centre.tolist())
        count = MESH_COUNT[p.shape]
        ext = p.extents
        flex = body.make_flex(
            f"piece_{i}", type="grid" if p.shape == "cube" else "ellipsoid", dim=3,
            dof="trilinear", count=[count] * 3, spacing=(ext / (count - 1)).tolist(),
            radius=0.0, mass=p.mass)
        mat = p.material
        flex.young = mat.young
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
        flex.solref = [0.01, 1.0]
        flex.solimp = [0.9999, 0.9999, 0.001, 0.5, 2.0]
        flex.rgba = _colour(mat.young)
    with warnings.catch_warnings():
        # MuJoCo warns that a trilinear flex "has no equality constraints or passive forces"
        # although its elasticity is active (checked in tests/test_viscoelastic.py).
        warnings.filterwarnings("ignore", message=".*no equality constraints or passive")
        model = spec.compile()
    scene = Scene(model=model, pieces=pieces, geometry=geometry, pose=pose)
    for kind, names in ((mujoco.mjtObj.mjOBJ_JOINT, ("hinge_left", "hinge_right", "lift")),
                        (mujoco.mjtObj.mjOBJ_ACTUATOR, ("servo_left", "servo_right",
                                                        "servo_lift")),
                        (mujoco.mjtObj.mjOBJ_GEOM, ("blade_left", "blade_right", "plate")),
                        (mujoco.mjtObj.mjOBJ_BODY, ("stage", "wrist"))):
        for name in names:
            scene.ids[name] = mujoco.mj_name2id(model, kind, name)
    scene.piece_flex = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_FLEX, f"piece_{i}")
                        for i in range(len(pieces))]
    return scene


def _colour(young: float) -> list[float]:
    """Soft foods warm and pale, hard foods dark: log-scaled over the study's range."""
    s = float(np.clip((math.log10(young) - 4) / (8.3 - 4), 0, 1))
    return [0.95 - 0.45 * s, 0.75 - 0.35 * s, 0.35 + 0.1 * s, 1.0]


def initial_state(scene: Scene) -> mujoco.MjData:
    """MjData at the open pose: blades at -theta_open, servos holding them there."""
    m = scene.model
    d = mujoco.MjData(m)
    q_open = -scene.pose.theta_open
    for side in ("left", "right"):
        d.qpos[m.jnt_qposadr[scene.ids[f"hinge_{side}"]]] = q_open
        d.ctrl[scene.ids[f"servo_{side}"]] = q_open
    mujoco.mj_forward(m, d)
    return d
