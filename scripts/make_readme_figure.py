"""The README picture: rendered frames of a fetch (open, clamped, lifted) over the traces.

Run: MUJOCO_GL=egl python scripts/make_readme_figure.py   (writes docs/fetch_trace.png)
"""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import mujoco
import numpy as np

from fetch_env.controller import PHASE_CODE, FetchAction, FetchSimulator
from fetch_env.layouts import single_block


def main() -> None:
    sim = FetchSimulator(single_block())
    scene = sim.scene_for("fetch")
    renderer = mujoco.Renderer(scene.model, 360, 480)
    frames: dict[str, np.ndarray] = {}
    want = {"open": 0.25, "clamped": 1.2, "lifted": 3.5}

    def grab(d: mujoco.MjData) -> None:
        for name, when in want.items():
            if name not in frames and d.time >= when:
                renderer.update_scene(d, camera="front")
                frames[name] = renderer.render().copy()

    r = sim.run("fetch", FetchAction(theta_d=0.045, omega=0.1, hold=1.0), observer=grab)
    tr = r.traces
    fig = plt.figure(figsize=(12, 6.2))
    for k, name in enumerate(want):
        ax = fig.add_subplot(2, 3, k + 1)
        ax.imshow(frames[name])
        ax.set_title(f"{name} (t = {want[name]:.2f} s)")
        ax.axis("off")
    ax = fig.add_subplot(2, 1, 2)
    moment = 0.5 * (tr["moment_left"] + tr["moment_right"])
    ax.plot(tr["t"], moment * 1e3, color="C0", label="moment on a half-spoon [mN m]")
    ax.plot(tr["t"], tr["lift"] * 1e4, color="C2", label="lift [0.1 mm]")
    ax.set_ylabel("moment [mN m], lift [0.1 mm]")
    ax2 = ax.twinx()
    ax2.plot(tr["t"], tr["force"][:, 2] * 1e3, color="C1", lw=0.8,
             label="vertical force of the food on the end-effector [mN]")
    ax2.set_ylabel("force [mN]")
    top = ax.get_ylim()[1]
    for name, code in PHASE_CODE.items():
        sel = tr["phase"] == code
        if sel.any():
            ax.axvspan(tr["t"][sel][0], tr["t"][sel][-1], alpha=0.06, color=f"C{code}")
            ax.text(tr["t"][sel].mean(), top * 0.92, name, ha="center")
    ax.set_xlabel("time [s]")
    ax.legend(loc="upper left", bbox_to_anchor=(0.0, 0.8))
    ax2.legend(loc="lower right")
    ax.set_title("15 mm, 0.2 MPa cube (g1 0.425, tau1 3.667 s, mu 0.3): clamp to 0.045 rad "
                 "at 0.1 rad/s, hold 1 s, lift 5 mm at 5 mm/s, hold in the air")
    fig.tight_layout()
    fig.savefig("docs/fetch_trace.png", dpi=90)
    print("wrote docs/fetch_trace.png")


if __name__ == "__main__":
    main()
