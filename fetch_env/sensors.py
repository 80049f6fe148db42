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

from collections.abc import Callable

import mujoco
import numpy as np

from fetch_env.scene import Scene


class ContactSensors:
    """Readout of the blades' contacts: the raw numbers are copied at each recorded sample
    (:meth:`copier`) and turned into readings for many samples at once (:meth:`readings`)."""

    # raw floats per sample: the two hinges' constraint forces, the two netforce sensors'
    # world-frame forces (2 x 3), and the two spoon bodies' orientations (2 x 9)
    RAW_SIZE = 26

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

    def copier(self, d: mujoco.MjData) -> Callable[[np.ndarray], None]:
        """A function that copies ``d``'s raw readings now into a row of :attr:`RAW_SIZE`
        floats (the views into ``d`` are fetched once, here)."""
        qfrc, sensordata, xmat = d.qfrc_constraint, d.sensordata, d.xmat
        hinge_dofs, force_rows, spoons = self.hinge_dofs, self.force_rows, self.spoon_bodies

        def copy(row: np.ndarray) -> None:
            np.take(qfrc, hinge_dofs, out=row[0:2], mode="clip")
            np.take(sensordata, force_rows, out=row[2:8], mode="clip")
            np.take(xmat, spoons, axis=0, out=row[8:26].reshape(2, 9), mode="clip")

        return copy

    def readings(self, raw: np.ndarray) -> dict[str, np.ndarray]:
        """Per sample (rows of ``raw``) and blade (index 0 left, 1 right): moment M [N m]
        (> 0 pushes the blade open), normal and tangential contact force [N], each (S, 2),
        and the total force of the food on the end-effector [N] (world frame), (S, 3).
        """
        moment = -raw[:, 0:2]
        f_sum = -raw[:, 2:8].reshape(-1, 2, 3)
        # Outward normal of each blade's inner face: the spoon body's y axis, away from the
        # food (-y left, +y right).
        n_out = raw[:, 8:26].reshape(-1, 2, 9)[:, :, 1::3] * self.out_sign  # (S, 2, 3)
        normal = (f_sum * n_out).sum(axis=2)
        tangential_vec = f_sum - normal[..., None] * n_out
        tangential = np.sqrt((tangential_vec * tangential_vec).sum(axis=2))
        return {"moment": moment, "normal": normal, "tangential": tangential,
                "force": f_sum[:, 0] + f_sum[:, 1]}

    def read(self, d: mujoco.MjData) -> dict[str, np.ndarray]:
        """The readings of ``d`` now (as :meth:`readings`, for one sample)."""
        row = np.empty(self.RAW_SIZE)
        self.copier(d)(row)
        return {k: v[0] for k, v in self.readings(row[None]).items()}
