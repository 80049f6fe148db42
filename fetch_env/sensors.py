"""What the robot's sensors read: the moment on each half-spoon, its contact force split into
normal and tangential parts, and the 3-D force on the end-effector.

MuJoCo's ``force``/``torque`` sensors are computed from ``cfrc_int``, which does not include
contacts with flexes (measured: they read only the blades' own weight while a piece hangs
between them), so the readings are assembled here from the constraint solver's contact forces:
exactly what an ideal, tared moment sensor on the hinge and force sensor on the wrist measure.
"""

from __future__ import annotations

import mujoco
import numpy as np

from fetch_env.scene import Scene


class ContactSensors:
    """Vectorized readout of the blade contacts of a scene (elliptic cones, condim 3).

    Called at every recorded sample, so it is a few batched numpy calls: a lookup table maps
    each contact's geoms to the blade it touches, one gather reads the contact forces, and one
    matrix product sums them per blade.
    """

    def __init__(self, scene: Scene) -> None:
        m = scene.model
        require_elliptic = m.opt.cone == mujoco.mjtCone.mjCONE_ELLIPTIC
        if not require_elliptic:
            raise ValueError("ContactSensors expects elliptic friction cones")
        blades = [scene.ids["blade_left"], scene.ids["blade_right"]]
        hinges = [scene.ids["hinge_left"], scene.ids["hinge_right"]]
        # Each hinge's generalized constraint force is exactly the moment of the contacts on
        # its half-spoon about the hinge axis, (r x f) . axis (the hinges have no limits or
        # friction loss; tests/test_fetch.py checks it against the contact sum).
        self.hinge_dofs = np.array([m.jnt_dofadr[j] for j in hinges])
        self.spoon_bodies = np.array([m.geom_bodyid[g] for g in blades])
        # geom id -> 1 (left blade), 2 (right blade), 0 (anything else); flex contacts carry
        # geom -1, which indexes the trailing 0.
        self.side_of = np.zeros(m.ngeom + 1, dtype=np.int64)
        self.side_of[blades[0]], self.side_of[blades[1]] = 1, 2
        self.rows = np.arange(3)
        # Per contact, its weight in the (left, right) sums, by [its blade's side, side of
        # its geom[1]]: the contact force acts on geom[1] along +normal, so it is flipped
        # where the blade is geom[0] (geom[1] is food, side 0), giving the force of the food
        # on the blade.
        self._weights = np.zeros((3, 3, 2))
        self._weights[1, :, 0] = self._weights[2, :, 1] = (-1.0, 1.0, 1.0)
        self._no_force = np.zeros((2, 3))
        self.out_sign = np.array([[-1.0], [1.0]])  # inner-face outward normal: -y left, +y right

    def read(self, d: mujoco.MjData) -> dict[str, np.ndarray]:
        """Per blade (index 0 left, 1 right): moment M [N m] (> 0 pushes the blade open),
        normal and tangential contact force [N], and the total force of the food on the
        end-effector [N] (world frame).
        """
        moment = -d.qfrc_constraint[self.hinge_dofs]
        f_sum = self._no_force
        nc = d.ncon
        if nc:
            con = d.contact
            geom_side = self.side_of[con.geom[:nc]]  # (c, 2)
            side = geom_side[:, 0] + geom_side[:, 1]  # blades never touch each other
            adr = con.efc_address[:nc]
            on = np.flatnonzero(side * (adr >= 0))
            if on.size:
                f_local = d.efc_force[adr[on, None] + self.rows]  # (c, 3) in the contact frame
                frames = con.frame[on]  # (c, 9): rows normal, t1, t2 of each contact frame
                weights = self._weights[side[on], geom_side[on, 1]].T  # (2, c)
                # sum_c w[b, c] f_local[c] @ frame[c] as one (2, 3c) @ (3c, 3) product
                f_sum = (weights[:, :, None] * f_local).reshape(2, -1) @ frames.reshape(-1, 3)
        # Outward normal of each blade's inner face: the spoon body's y axis, away from the
        # food (-y left, +y right).
        n_out = d.xmat[self.spoon_bodies, 1::3] * self.out_sign  # (2, 3)
        normal = (f_sum * n_out).sum(axis=1)
        tangential_vec = f_sum - normal[:, None] * n_out
        tangential = np.sqrt((tangential_vec * tangential_vec).sum(axis=1))
        return {"moment": moment, "normal": normal, "tangential": tangential,
                "force": f_sum[0] + f_sum[1]}
