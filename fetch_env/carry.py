"""The carry toward the mouth: the closed pair rolled about the clamp direction in the air.

Once the bite is lifted, the robot turns it toward the person.  The half-spoons' faces form a
V that narrows downward, so a load in the clamp plane (gravity, the lift) pushes a piece into
the wedge and is held whatever the squeeze.  A load along the hinge axis (x) is not wedged:
there only the faces' friction holds the piece, ``2 mu N >= m a`` with ``N`` the grip's
normal force after the clamp has relaxed.  Rolling the pair by ``phi`` about the clamp
direction (y) puts ``g sin(phi)`` of gravity along the hinge axis: what a spoon or a pair of
chopsticks tipped toward a mouth meets.

The roll is simulated in the pair's frame.  The blades stay where the lift left them and
every node of a held piece feels gravity rotated by ``phi``: an extra body force
``m g (sin(phi), 0, 1 - cos(phi))`` (MuJoCo's ``xfrc_applied``), ramped by half a cosine
from 0 to ``phi`` over ``ramp`` seconds so that the load comes on quasi-statically.  The
roll is taken about an axis through the bite, and its own rates are neglected: at most
``pi phi / (2 ramp)`` and ``pi^2 phi / (2 ramp^2)``, which for 0.5 rad over the default
0.4 s give 0.05 m/s^2 of centripetal and 0.19 m/s^2 of angular acceleration 12 mm from the
axis, against ``g sin(0.5)`` = 4.7 m/s^2 along it.  Pieces left on the plate feel nothing:
the plate does not roll.
"""

from __future__ import annotations

import math

import mujoco
import numpy as np

from fetch_env.metrics import PiecePositions
from fetch_env.scene import Scene

TILT_RAMP = 0.4  # [s] default time the roll takes (see the module's docstring)


def tilt_angles(elapsed: np.ndarray, tilt: float, ramp: float) -> np.ndarray:
    """The roll angle [rad] at ``elapsed`` seconds into the air hold: half a cosine from 0 to
    ``tilt`` over ``ramp`` seconds, then held."""
    s = np.clip(np.asarray(elapsed, dtype=float) / ramp, 0.0, 1.0)
    return tilt * 0.5 * (1.0 - np.cos(math.pi * s))


class TiltLoad:
    """The rotated gravity's extra force on the nodes of the pieces the pair holds, step by
    step through a fetch whose roll angle at each step is ``angles``.

    The pieces are chosen at the first step that rolls: those whose lowest vertex is above
    ``min_height`` (lifted off the plate, as the fetch counts them), read by the run's own
    ``positions`` meter."""

    def __init__(self, scene: Scene, angles: np.ndarray, min_height: float,
                 positions: PiecePositions) -> None:
        m = scene.model
        self._nodes: list[np.ndarray] = []
        for f in scene.piece_flex:
            adr, num = m.flex_nodeadr[f], m.flex_nodenum[f]
            self._nodes.append(np.asarray(m.flex_nodebodyid[adr:adr + num]))
        self._mass = m.body_mass
        self._g = float(-m.opt.gravity[2])
        self._positions = positions
        self._min_height = min_height
        rolled = np.flatnonzero(np.asarray(angles) > 0)
        self.first = int(rolled[0]) if rolled.size else len(angles)  # the first rolled step
        self._angles = np.asarray(angles, dtype=float).tolist()
        self.held = np.zeros(len(self._nodes), dtype=bool)
        self._bodies = np.zeros(0, dtype=np.intp)
        self._weight = np.zeros(0)
        self._phi = math.nan  # the angle the nodes' force was last set for

    def step(self, data: mujoco.MjData, i: int) -> None:
        """Before physics step ``i`` (at or past :attr:`first`): set the held nodes' force."""
        if i == self.first:
            low, _ = self._positions(data)
            self.held = low > self._min_height
            chosen = [nodes for nodes, h in zip(self._nodes, self.held, strict=True) if h]
            self._bodies = np.concatenate(chosen) if chosen else np.zeros(0, dtype=np.intp)
            self._weight = self._mass[self._bodies] * self._g
        phi = self._angles[i]
        if self._bodies.size and phi != self._phi:  # held at the full roll: already set
            self._phi = phi
            data.xfrc_applied[self._bodies, 0] = self._weight * math.sin(phi)
            data.xfrc_applied[self._bodies, 2] = self._weight * (1.0 - math.cos(phi))
