"""Frames of an episode for ``render_mode="rgb_array"`` / ``"rgb_array_list"`` / ``"human"``.

The simulator (``FetchSimulator.run``) does not hand out its ``MjData`` while it steps, so the
frames of the clamp and the lift are a *replay* from what a run returns: the hinge angle and
the stage height come from the recorded traces (exact at 100 Hz), and each piece is moved
rigidly from its rest pose toward the final pose the run reports, in step with the lift.  The
blades' motion is therefore exact; the pieces' deformation during the clamp is not drawn.
(An observer hook in the controller would make the pieces exact too; see the issue notes.)
"""

from __future__ import annotations

import mujoco
import numpy as np

from fetch_env.errors import require, require_int
from fetch_env.scene import Scene, initial_state

CAMERAS: tuple[str, ...] = ("side", "front")  # the base scene's cameras


class EpisodeRenderer:
    """Off-screen frames of a scene at rest and replays of a fetch (RGB uint8 arrays)."""

    def __init__(self, width: int, height: int, camera: str) -> None:
        for name, value in (("width", width), ("height", height)):
            require_int(name, value)
            require(16 <= value <= 4096, name, value, "in [16, 4096] px")
        require(isinstance(camera, str) and camera in CAMERAS, "camera", camera,
                f"one of {CAMERAS}")
        self.width = width
        self.height = height
        self.camera = camera
        self._renderer: mujoco.Renderer | None = None
        self._model: mujoco.MjModel | None = None

    def _renderer_for(self, model: mujoco.MjModel) -> mujoco.Renderer:
        if self._model is not model:
            self.close()
            # The base scene sets offwidth/offheight 640x480; larger frames need a larger
            # offscreen buffer, set on this model only.
            model.vis.global_.offwidth = max(model.vis.global_.offwidth, self.width)
            model.vis.global_.offheight = max(model.vis.global_.offheight, self.height)
            self._renderer = mujoco.Renderer(model, self.height, self.width)
            self._model = model
        assert self._renderer is not None
        return self._renderer

    def _draw(self, scene: Scene, data: mujoco.MjData) -> np.ndarray:
        r = self._renderer_for(scene.model)
        r.update_scene(data, camera=self.camera)
        return r.render().copy()

    def rest_frame(self, scene: Scene) -> np.ndarray:
        """The scene as the episode starts: pieces on the plate, half-spoons open."""
        require(isinstance(scene, Scene), "scene", scene, "a Scene (build_scene)")
        return self._draw(scene, initial_state(scene))

    def replay(self, scene: Scene, traces: dict[str, np.ndarray], pieces: list[dict],
               fps: float) -> list[np.ndarray]:
        """Frames at ``fps`` over a fetch run (see the module docstring for what is exact)."""
        require(isinstance(scene, Scene), "scene", scene, "a Scene (build_scene)")
        require(isinstance(fps, int | float) and 0 < fps <= 1000, "fps", fps, "in (0, 1000]")
        m = scene.model
        d = initial_state(scene)
        q_hinge = [m.jnt_qposadr[scene.ids[f"hinge_{s}"]] for s in ("left", "right")]
        q_lift = m.jnt_qposadr[scene.ids["lift"]]
        hinge_open = [float(d.qpos[a]) for a in q_hinge]
        qpos0 = d.qpos.copy()
        # Each piece's node joints (three slides per node of its trilinear flex).
        moves = []
        for k, f in enumerate(scene.piece_flex):
            v = d.flexvert_xpos[m.flex_vertadr[f]:m.flex_vertadr[f] + m.flex_vertnum[f]]
            delta = np.asarray(pieces[k]["final_centre"]) - v.mean(axis=0)
            bodies = m.flex_nodebodyid[m.flex_nodeadr[f]:m.flex_nodeadr[f] + m.flex_nodenum[f]]
            joints = [j for j in range(m.njnt) if m.jnt_bodyid[j] in set(bodies.tolist())]
            adr = np.array([m.jnt_qposadr[j] for j in joints], dtype=int)
            axes = np.array([m.jnt_axis[j] for j in joints])
            moves.append((adr, axes @ delta))
        t = traces["t"]
        lift = traces["lift"]
        top = float(lift.max())
        frames = []
        for tf in np.arange(0.0, float(t[-1]) + 1e-9, 1.0 / fps):
            i = min(int(np.searchsorted(t, tf)), len(t) - 1)
            d.qpos[:] = qpos0
            for a, q0 in zip(q_hinge, hinge_open, strict=True):
                d.qpos[a] = q0 + traces["theta"][i]
            d.qpos[q_lift] = lift[i]
            progress = float(np.clip(lift[i] / top, 0.0, 1.0)) if top > 0 else 0.0
            for adr, shift in moves:
                d.qpos[adr] += progress * shift
            mujoco.mj_forward(m, d)
            frames.append(self._draw(scene, d))
        return frames

    def close(self) -> None:
        if self._renderer is not None:
            self._renderer.close()
        self._renderer = None
        self._model = None
