"""What the robot's sensors read: the moment on each half-spoon, its contact force split into
normal and tangential parts, and the 3-D force on the end-effector.

MuJoCo's ``force``/``torque`` sensors are computed from ``cfrc_int``, which does not include
contacts with flexes (measured: they read only the blades' own weight while a piece hangs
between them).  So the moment is each hinge's constraint force and the forces come from the
scene's ``contact`` sensors (``reduce="netforce"``: MuJoCo sums every contact on a blade,
flex contacts included, in C at each step): exactly what an ideal, tared moment sensor on the
hinge and force sensor on the wrist measure.
"""

from __future__ import annotations

import mujoco
import numpy as np

from fetch_env.scene import Scene


class ContactSensors:
    """Readout of the blades' contacts; called at every recorded sample, so a few batched
    numpy calls on MuJoCo's own sums."""

    def __init__(self, scene: Scene) -> None:
        m = scene.model
        blades = [scene.ids["blade_left"], scene.ids["blade_right"]]
        hinges = [scene.ids["hinge_left"], scene.ids["hinge_right"]]
        # Each hinge's generalized constraint force is exactly the moment of the contacts on
        # its half-spoon about the hinge axis, (r x f) . axis (the hinges have no limits or
        # friction loss; tests/test_fetch.py checks it against a contact-by-contact sum).
        self.hinge_dofs = np.array([m.jnt_dofadr[j] for j in hinges])
        self.spoon_bodies = np.array([m.geom_bodyid[g] for g in blades])
        # The netforce sensors' world-frame force, (left, right) x 3 rows of sensordata.  Its
        # normal points from geom1 (the blade) to the food, so it is the force on the food:
        # negated, the force of the food on the blade.
        adr = [m.sensor_adr[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_SENSOR, f"contact_{side}")]
               for side in ("left", "right")]
        self.force_rows = np.concatenate([np.arange(a, a + 3) for a in adr])
        self.out_sign = np.array([[-1.0], [1.0]])  # inner-face outward normal: -y left, +y right

    def read(self, d: mujoco.MjData) -> dict[str, np.ndarray]:
        """Per blade (index 0 left, 1 right): moment M [N m] (> 0 pushes the blade open),
        normal and tangential contact force [N], and the total force of the food on the
        end-effector [N] (world frame).
        """
        moment = -d.qfrc_constraint[self.hinge_dofs]
        f_sum = -d.sensordata[self.force_rows].reshape(2, 3)
        # Outward normal of each blade's inner face: the spoon body's y axis, away from the
        # food (-y left, +y right).
        n_out = d.xmat[self.spoon_bodies, 1::3] * self.out_sign  # (2, 3)
        normal = (f_sum * n_out).sum(axis=1)
        tangential_vec = f_sum - normal[:, None] * n_out
        tangential = np.sqrt((tangential_vec * tangential_vec).sum(axis=1))
        return {"moment": moment, "normal": normal, "tangential": tangential,
                "force": f_sum[0] + f_sum[1]}
