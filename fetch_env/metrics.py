"""Deformation and outcome measures: logarithmic strain per element, fetched or not."""

from __future__ import annotations

import mujoco
import numpy as np

from fetch_env.scene import Scene


class StrainMeter:
    """Maximum logarithmic strain (LE) of each piece, per tetrahedral element.

    For each element the deformation gradient is ``F = D_s D_m^{-1}`` (current and rest edge
    matrices); LE is the largest ``|log lambda_i|`` over its principal stretches (the singular
    values of F), as ABAQUS reports LE.
    """

    def __init__(self, scene: Scene, rest: mujoco.MjData) -> None:
        m = scene.model
        elems, owner = [], []
        for i, f in enumerate(scene.piece_flex):
            vadr = m.flex_vertadr[f]
            e = m.flex_elem[m.flex_elemdataadr[f]:m.flex_elemdataadr[f] + 4 * m.flex_elemnum[f]]
            elems.append(np.asarray(e).reshape(-1, 4) + vadr)
            owner.append(np.full(m.flex_elemnum[f], i))
        self.elems = np.concatenate(elems)
        self.owner = np.concatenate(owner)
        # each piece's elements are contiguous: the first one's index per piece, for reduceat
        self.first = np.searchsorted(self.owner, np.arange(len(scene.pieces)))
        self.n_pieces = len(scene.pieces)
        X = rest.flexvert_xpos[self.elems]  # (E, 4, 3)
        Dm = (X[:, 1:] - X[:, :1]).transpose(0, 2, 1)
        self.Dm_inv = np.linalg.inv(Dm)

    def element_strain(self, data: mujoco.MjData) -> np.ndarray:
        """LE of every element, shape (E,).

        The principal stretches are the square roots of the eigenvalues of C = F^T F, so
        LE = max |log lambda| = 0.5 max(|log c_min|, |log c_max|) (eigvalsh of the symmetric
        C is cheaper than an SVD of F).
        """
        x = data.flexvert_xpos[self.elems]
        Ds = (x[:, 1:] - x[:, :1]).transpose(0, 2, 1)
        F = Ds @ self.Dm_inv
        c = np.linalg.eigvalsh(np.einsum("eki,ekj->eij", F, F))
        log_c = np.log(np.clip(c[:, [0, 2]], 1e-24, None))
        return 0.5 * np.abs(log_c).max(axis=1)

    def piece_strain(self, data: mujoco.MjData) -> np.ndarray:
        """Max LE over each piece's elements, shape (P,)."""
        return np.maximum.reduceat(self.element_strain(data), self.first)


def piece_positions(scene: Scene, data: mujoco.MjData) -> tuple[np.ndarray, np.ndarray]:
    """Lowest vertex height and vertex centroid of each piece: (P,), (P, 3)."""
    m = scene.model
    low, centre = [], []
    for f in scene.piece_flex:
        v = data.flexvert_xpos[m.flex_vertadr[f]:m.flex_vertadr[f] + m.flex_vertnum[f]]
        low.append(v[:, 2].min())
        centre.append(v.mean(axis=0))
    return np.array(low), np.array(centre)


def residual_plastic_strain(scene: Scene, data: mujoco.MjData) -> list[float | None]:
    """Per piece: norm of the plastic strain stored by MuJoCo, or None where no yield is set."""
    m = scene.model
    out: list[float | None] = []
    for p, f in zip(scene.pieces, scene.piece_flex, strict=True):
        adr = m.flex_plasticadr[f]
        if p.material.yield_strain <= 0 or adr < 0:
            out.append(None)
            continue
        eps = np.asarray(data.plastic[adr:adr + 6])
        out.append(float(np.linalg.norm(eps)))
    return out


def blade_overlap(scene: Scene, data: mujoco.MjData) -> float:
    """Deepest reach of any food vertex into either blade, from its inner face [m].

    0 when nothing touches; a few tenths of a millimetre in a firm clamp (contact
    compliance); more than the blade's thickness means a piece passed through it.
    """
    m = scene.model
    v = data.flexvert_xpos
    deepest = 0.0
    for side, inward in (("left", 1.0), ("right", -1.0)):
        g = scene.ids[f"blade_{side}"]
        half = m.geom_size[g]
        local = (v - data.geom_xpos[g]) @ data.geom_xmat[g].reshape(3, 3)
        inside = (np.abs(local[:, 0]) <= half[0]) & (np.abs(local[:, 2]) <= half[2])
        if inside.any():
            # depth below the inner face (local y = +half for the left blade, -half right)
            depth = half[1] - inward * local[inside, 1]
            deepest = max(deepest, float(depth.max()))
    return deepest
