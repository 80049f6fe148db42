"""Deformation and outcome measures: logarithmic strain per element, fetched or not."""

from __future__ import annotations

import mujoco
import numpy as np
import scipy.sparse

from fetch_env.scene import Scene


def extreme_eigenvalues(C: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Smallest and largest eigenvalues of symmetric 3x3 matrices C, shape (E, 3, 3).

    Closed form (the trigonometric solution of the characteristic cubic, Smith 1961): a
    dozen elementwise array operations, 7x faster than ``np.linalg.eigvalsh`` on the ~1000
    elements of a diced mix (36 against 252 us measured) and equal to it within ~1e-15 (a
    few 1e-9 of the eigenvalue scale where two eigenvalues nearly coincide; tested).
    """
    a, b, c = C[:, 0, 0], C[:, 1, 1], C[:, 2, 2]
    d, e, f = C[:, 0, 1], C[:, 0, 2], C[:, 1, 2]
    q = (a + b + c) / 3.0
    aq, bq, cq = a - q, b - q, c - q
    p = np.sqrt((aq * aq + bq * bq + cq * cq + 2.0 * (d * d + e * e + f * f)) / 6.0)
    # det(C - q I) / (2 p^3); p -> 0 (an isotropic C) leaves r = 0 and both answers q
    det = aq * (bq * cq - f * f) - d * (d * cq - f * e) + e * (d * f - bq * e)
    r = det / (2.0 * np.maximum(p, 1e-100) ** 3)
    phi = np.arccos(np.clip(r, -1.0, 1.0)) / 3.0
    return q + 2.0 * p * np.cos(phi + 2.0 * np.pi / 3.0), q + 2.0 * p * np.cos(phi)


class StrainMeter:
    """Maximum logarithmic strain (LE) of each piece, per tetrahedral element.

    For each element the deformation gradient is ``F = D_s D_m^{-1}`` (current and rest edge
    matrices); LE is the largest ``|log lambda_i|`` over its principal stretches (the singular
    values of F), as ABAQUS reports LE.  ``F`` is linear in the vertex positions, so every
    element's ``F`` comes from one sparse matrix product (``scipy.sparse``), for a whole stack
    of samples at once (:class:`fetch_env.recording.TraceRecorder` meters a run in batches).
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
        Dm_inv = np.linalg.inv(Dm)
        # F[e, i, j] = sum_k (x[v_k+1, i] - x[v_0, i]) Dm_inv[e, k, j]: a (9E, 3V) matrix B
        # with F.ravel() = B @ x.ravel().
        n_el = len(self.elems)
        e_idx, i_idx, j_idx, k_idx = np.meshgrid(np.arange(n_el), np.arange(3), np.arange(3),
                                                 np.arange(3), indexing="ij")
        row = (e_idx * 9 + i_idx * 3 + j_idx).ravel()
        coef = Dm_inv[e_idx, k_idx, j_idx].ravel()
        col_tip = (self.elems[e_idx, k_idx + 1] * 3 + i_idx).ravel()
        col_base = (self.elems[e_idx, 0] * 3 + i_idx).ravel()
        n_cols = rest.flexvert_xpos.size
        self.B = scipy.sparse.csr_array(
            (np.concatenate([coef, -coef]), (np.concatenate([row, row]),
                                             np.concatenate([col_tip, col_base]))),
            shape=(9 * n_el, n_cols))

    def element_strain(self, data: mujoco.MjData) -> np.ndarray:
        """LE of every element now, shape (E,)."""
        return self.element_strain_of(data.flexvert_xpos[None])[0]

    def element_strain_of(self, xpos: np.ndarray) -> np.ndarray:
        """LE of every element for a stack of vertex positions (S, V, 3): shape (S, E).

        The principal stretches are the square roots of the eigenvalues of C = F^T F, so
        LE = max |log lambda| = 0.5 max(|log c_min|, |log c_max|), which for
        c_min <= c_max is 0.5 log max(c_max, 1 / c_min) (one log instead of two).
        """
        n_samples = xpos.shape[0]
        F = (self.B @ xpos.reshape(n_samples, -1).T).T.reshape(-1, 3, 3)
        c_min, c_max = extreme_eigenvalues(F.transpose(0, 2, 1) @ F)
        # (a degenerate, crushed element can give c_min <= 0: 1e-24 caps its LE at ~27.6)
        le = 0.5 * np.log(np.maximum(c_max, 1.0 / np.maximum(c_min, 1e-24)))
        return le.reshape(n_samples, -1)

    def piece_strain(self, data: mujoco.MjData) -> np.ndarray:
        """Max LE over each piece's elements now, shape (P,)."""
        return self.piece_strain_of(data.flexvert_xpos[None])[0]

    def piece_strain_of(self, xpos: np.ndarray) -> np.ndarray:
        """Max LE over each piece's elements for a stack of vertex positions (S, V, 3):
        shape (S, P)."""
        return np.maximum.reduceat(self.element_strain_of(xpos), self.first, axis=1)


class PiecePositions:
    """Lowest vertex height and vertex centroid of each piece, read in a few batched calls."""

    def __init__(self, scene: Scene) -> None:
        m = scene.model
        adr = np.array([m.flex_vertadr[f] for f in scene.piece_flex])
        num = np.array([m.flex_vertnum[f] for f in scene.piece_flex])
        self.verts = np.concatenate([np.arange(a, a + n) for a, n in zip(adr, num, strict=True)])
        self.first = np.concatenate([[0], np.cumsum(num)[:-1]])
        self.num = num

    def lowest_of(self, xpos: np.ndarray) -> np.ndarray:
        """Lowest vertex height of each piece for a stack of vertex positions (S, V, 3),
        shape (S, P): the per-sample plate pass-through check."""
        return np.minimum.reduceat(xpos[:, self.verts, 2], self.first, axis=1)

    def piece_max(self, per_vertex: np.ndarray) -> np.ndarray:
        """Each piece's largest value of a per-vertex quantity (S, V): shape (S, P)."""
        return np.maximum.reduceat(per_vertex[:, self.verts], self.first, axis=1)

    def __call__(self, data: mujoco.MjData) -> tuple[np.ndarray, np.ndarray]:
        v = data.flexvert_xpos[self.verts]
        low = np.minimum.reduceat(v[:, 2], self.first)
        centre = np.add.reduceat(v, self.first, axis=0) / self.num[:, None]
        return low, centre


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


class BladeOverlap:
    """Deepest reach of any food vertex into either blade, from its inner face [m].

    0 when nothing touches; a few tenths of a millimetre in a firm clamp (contact
    compliance); more than the blade's thickness means a piece passed through it.
    """

    def __init__(self, scene: Scene) -> None:
        m = scene.model
        self.geoms = np.array([scene.ids["blade_left"], scene.ids["blade_right"]])
        self.half = m.geom_size[self.geoms][:, None, :]  # (2, 1, 3)
        self.inward = np.array([1.0, -1.0])[:, None]  # inner face at local +y (left), -y

    def of(self, xpos: np.ndarray, blade_pos: np.ndarray, blade_mat: np.ndarray) -> np.ndarray:
        """Each vertex's reach into either blade (0 outside both), shape (S, V): from vertex
        positions (S, V, 3) and the blades' ``geom_xpos`` (S, 2, 3) and ``geom_xmat``
        (S, 2, 9) rows at each sample."""
        # vertices in each blade's frame, (S, 2, V, 3)
        local = (xpos[:, None] - blade_pos[:, :, None]) @ blade_mat.reshape(-1, 2, 3, 3)
        half = self.half
        inside = (np.abs(local[..., 0]) <= half[..., 0]) & (np.abs(local[..., 2]) <= half[..., 2])
        depth = half[..., 1] - self.inward * local[..., 1]
        return np.max(depth, axis=1, where=inside, initial=0.0)
