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
    """Vectorized readout of the blade contacts of a scene (elliptic cones, condim 3)."""

    def __init__(self, scene: Scene) -> None:
        m = scene.model
        require_elliptic = m.opt.cone == mujoco.mjtCone.mjCONE_ELLIPTIC
        if not require_elliptic:
            raise ValueError("ContactSensors expects elliptic friction cones")
        self.blades = np.array([scene.ids["blade_left"], scene.ids["blade_right"]])
        self.hinges = np.array([scene.ids["hinge_left"], scene.ids["hinge_right"]])
        self.spoon_bodies = np.array([m.geom_bodyid[g] for g in self.blades])

    def read(self, d: mujoco.MjData) -> dict[str, np.ndarray]:
        """Per blade (index 0 left, 1 right): moment M [N m] (> 0 pushes the blade open),
        normal and tangential contact force [N], and the total force of the food on the
        end-effector [N] (world frame).
        """
        moment = np.zeros(2)
        normal = np.zeros(2)
        tangential = np.zeros(2)
        total = np.zeros(3)
        nc = d.ncon
        if not nc:
            return {"moment": moment, "normal": normal, "tangential": tangential,
                    "force": total}
        con = d.contact
        geom = con.geom[:nc]
        # which blade (0 left, 1 right) each contact touches, -1 for none; one pass for both
        side = np.full(nc, -1)
        for k, g in enumerate(self.blades):
            side[(geom[:, 0] == g) | (geom[:, 1] == g)] = k
        adr = con.efc_address[:nc]
        on = (side >= 0) & (adr >= 0)
        if not on.any():
            return {"moment": moment, "normal": normal, "tangential": tangential,
                    "force": total}
        side, adr, geom = side[on], adr[on], geom[on]
        f_local = d.efc_force[adr[:, None] + np.arange(3)]  # (c, 3) in the contact frame
        frames = con.frame[:nc][on].reshape(-1, 3, 3)  # rows: normal, t1, t2
        f_world = np.einsum("ci,cij->cj", f_local, frames)
        # The contact force acts on geom[1] along +normal (from geom[0] to geom[1]); flip it
        # where the blade is geom[0], giving the force of the food on the blade.
        f_blade = f_world * np.where(geom[:, 1] == self.blades[side], 1.0, -1.0)[:, None]
        lever = con.pos[:nc][on] - d.xanchor[self.hinges][side]
        axis = d.xaxis[self.hinges][side]  # each hinge's closing direction
        # moment about the hinge axis, (r x f) . axis, as a triple product; > 0 pushes open
        torque_on_axis = np.einsum("ci,ci->c", np.cross(lever, f_blade), axis)
        for k in (0, 1):
            mine = side == k
            if not mine.any():
                continue
            moment[k] = -float(torque_on_axis[mine].sum())
            f_sum = f_blade[mine].sum(axis=0)
            # Outward normal of the blade's inner face: the spoon body's -y (left) or +y
            # (right) axis, i.e. away from the food.
            y_axis = d.xmat[self.spoon_bodies[k]].reshape(3, 3)[:, 1]
            n_out = y_axis if k == 1 else -y_axis
            normal[k] = float(f_sum @ n_out)
            tangential[k] = float(np.linalg.norm(f_sum - normal[k] * n_out))
            total += f_sum
        return {"moment": moment, "normal": normal, "tangential": tangential, "force": total}
