"""A cube between two rigid plates it sticks to: the material law on its own."""

from __future__ import annotations

import warnings

import mujoco
import numpy as np

from fetch_env.layouts import Piece
from fetch_env.materials import Material
from fetch_env.scene import Geometry, PoseInfo, Scene
from fetch_env.viscoelastic import PronyRelaxation

PLATES_XML = """
<mujoco>
  <option timestep="0.001" integrator="discrete" solver="Newton" tolerance="1e-10" impratio="1000"
          cone="elliptic" gravity="0 0 0"/>
  <default>
    <geom solref="0.002 1" solimp="0.9999 0.9999 0.001 0.5 2" friction="2 0.005 0.0001"/>
  </default>
  <worldbody>
    <geom name="bottom" type="box" size="0.03 0.03 0.005" pos="0 0 -0.005" contype="2"
          conaffinity="1"/>
    <body name="top" pos="0 0 {top}">
      <joint name="press" type="slide" axis="0 0 1" armature="1"/>
      <geom name="top" type="box" size="0.03 0.03 0.005" pos="0 0 0.005" contype="2"
            conaffinity="1" mass="0.1"/>
    </body>
  </worldbody>
  <actuator><position name="press" joint="press" kp="1e7" kv="1e4"/></actuator>
</mujoco>
"""


def press(material: Material, size: float = 0.015, strain: float = 0.03,
          duration: float | None = None, ramp: float = 0.005) -> tuple[np.ndarray, np.ndarray,
                                                                      np.ndarray]:
    """Step-compress a cube by ``strain`` and hold; returns t, plate force, actual strain."""
    spec = mujoco.MjSpec.from_string(PLATES_XML.format(top=size))
    body = spec.worldbody.add_body(name="piece_0", pos=[0, 0, size / 2])
    flex = body.make_flex("piece_0", type="grid", dim=3, dof="trilinear", count=[3, 3, 3],
                          spacing=[size / 2] * 3, radius=0.0, mass=material.density * size**3)
    flex.young, flex.poisson = material.young, material.poisson
    flex.friction = [2.0, 0.005, 0.0001]
    flex.contype, flex.conaffinity = 1, 2
    flex.solref = [0.002, 1.0]
    flex.solimp = [0.9999, 0.9999, 0.001, 0.5, 2.0]
    with warnings.catch_warnings():  # the same spurious warning scene.build_scene filters
        warnings.filterwarnings("ignore", message=".*no equality constraints or passive")
        model = spec.compile()
    scene = Scene(model=model, pieces=(Piece("cube", size, material),), geometry=Geometry(),
                  pose=PoseInfo(0.05, 0.0, 0.0, 0.2, 0.01, (0.0, 0.0), 0.061),
                  piece_flex=[0])
    d = mujoco.MjData(model)
    prony = PronyRelaxation(scene)
    mujoco.mj_forward(model, d)
    prony.reset(d)
    top = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, "top")
    dt = model.opt.timestep
    duration = duration or 4 * material.tau1
    n = round((ramp + duration) / dt)
    t_out, f_out, e_out = np.zeros(n), np.zeros(n), np.zeros(n)
    nodes = prony.node_bodies[0]
    for i in range(n):
        t = (i + 1) * dt
        lead = strain * size / ramp * 1e-3 if t < ramp else 0.0  # servo velocity feed-forward
        d.ctrl[0] = -strain * size * min(t / ramp, 1.0) - lead
        prony.apply(d)
        mujoco.mj_step(model, d)
        force = 0.0
        for c in range(d.ncon):
            con = d.contact[c]
            if top in (con.geom[0], con.geom[1]) and con.efc_address >= 0:
                force += d.efc_force[con.efc_address]
        z = d.xpos[nodes][:, 2]
        t_out[i], f_out[i] = t - ramp, force
        e_out[i] = 1.0 - (z.max() - z.min()) / size
    return t_out, f_out, e_out
