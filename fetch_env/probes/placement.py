"""Which piece the probes clamp and how far: the piece nearest the layout's centre, the angle
at which the blade faces first reach its rest surface (what a depth camera sees) and the
angle that squeezes it by a set share of its width."""

from __future__ import annotations

import math

import numpy as np

from fetch_env.controller import FetchSimulator
from fetch_env.errors import require, require_finite, require_pieces, require_type
from fetch_env.layouts import Piece
from fetch_env.scene import Scene, initial_state


def probe_piece_index(pieces: tuple[Piece, ...]) -> int:
    """The piece nearest the layout's centre (ties: the lowest index)."""
    require_pieces("pieces", pieces)
    xy = np.array([[p.x, p.y] for p in pieces])
    centre = (xy.min(axis=0) + xy.max(axis=0)) / 2
    return int(np.argmin(np.linalg.norm(xy - centre, axis=1)))


def first_contact_angle(scene: Scene) -> tuple[float, float, float]:
    """Where the blade faces first touch the piece, from its rest surface (a depth camera).

    Each face is at ``pose.face_y(theta, depth)`` from the hinge plane at ``depth`` below the
    axis; a surface vertex at lateral distance ``y`` and depth ``h`` is reached when
    ``face_offset / cos(theta) - h tan(theta) = y`` (solved by Newton's method for every
    vertex above the blade tip).

    Returns:
        (theta_contact [rad], depth of the first-touched vertex [m], the piece's half-width
        across the faces [m]).
    """
    require_type("scene", scene, Scene, "a Scene (build_scene)")
    d = initial_state(scene)
    pose = scene.pose
    v = np.asarray(d.flexvert_xpos)
    lateral = np.abs(v[:, 1] - pose.stage_xy[1])
    depth = pose.hinge_height - v[:, 2]
    reach = depth < scene.geometry.blade_length
    if not reach.any():
        return 0.0, pose.L, float(lateral.max())
    y, h = lateral[reach], depth[reach]
    th = np.zeros(y.size)
    for _ in range(8):
        f = pose.face_offset / np.cos(th) - h * np.tan(th) - y
        df = pose.face_offset * np.sin(th) / np.cos(th) ** 2 - h / np.cos(th) ** 2
        th = th - f / df
    k = int(np.argmin(th))
    return float(max(th[k], 0.0)), float(h[k]), float(lateral.max())


def probe_angle(sim: FetchSimulator, strain: float, experiment: str) -> float:
    """Clamp angle squeezing the piece by ``strain`` of its width past first contact.

    Small-angle travel of the contact point is ``depth * theta``; the result stays below
    the angle at which the faces would meet.
    """
    require_type("sim", sim, FetchSimulator, "a FetchSimulator")
    require_finite("strain", strain)
    require(0 < strain <= 1, "strain", strain, "in (0, 1]")
    scene = sim.scene_for(experiment)
    theta_c, depth, half_width = first_contact_angle(scene)
    theta = theta_c + strain * half_width / depth
    closed = getattr(scene.pose, "theta_closed", math.inf)
    return float(min(theta, 0.9 * closed))
