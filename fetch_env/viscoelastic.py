"""Prony-series viscoelasticity on top of MuJoCo's flex elasticity.

MuJoCo 4 computes the elastic force of a one-cell trilinear flex as a corotational linear
element: ``f = R K (R^T x - X0)``, with ``K`` the compiled 24x24 cell stiffness
(``mjModel.flex_stiffness``, scaled by the flex's Young's modulus), ``x`` the 8 node
positions and ``R`` the rotation of the polar decomposition of the deformation gradient at
the cell centre.  (``tests/test_viscoelastic.py`` checks this against ``qfrc_passive`` on
randomly deformed and rotated pieces.)

Because that law is linear in the corotated displacement ``u = R^T x - X0``, a standard
linear solid / Prony series is exact on the same discretization: with MuJoCo's modulus set
to the instantaneous ``E_0``, each Prony term k keeps a lagged displacement ``u_k`` with
``du_k/dt = (u - u_k) / tau_k`` (updated exactly over a step) and adds the force
``-g_k R K u_k``.  At t = 0+ the total is ``K u`` (E_0); once relaxed it is
``(1 - sum g_k) K u`` (E_inf); in between it follows E(t) of the Prony series.

The force goes into ``mjData.qfrc_applied`` of the node slide joints, owned by this object
(no global MuJoCo callback), so any number of simulations can run in one process.
"""

from __future__ import annotations

import mujoco
import numpy as np

from fetch_env.scene import Scene

_CORNER_BITS = np.array([[i >> 2 & 1, i >> 1 & 1, i & 1] for i in range(8)], dtype=float)


def _centre_gradients(rest_nodes: np.ndarray) -> np.ndarray:
    """Trilinear shape-function gradients dN_i/dX at the cell centre, shape (P, 8, 3).

    Node order is MuJoCo's (z fastest, then y, then x).
    """
    h = rest_nodes.max(axis=1) - rest_nodes.min(axis=1)  # (P, 3) cell edge lengths
    signs = np.where(_CORNER_BITS == 1, 1.0, -1.0)  # (8, 3)
    return 0.25 * signs[None, :, :] / h[:, None, :]


def corotation(x: np.ndarray, grad: np.ndarray) -> np.ndarray:
    """Rotation of the polar decomposition of F = sum_i x_i (x) dN_i at the centre, (P, 3, 3)."""
    F = x.transpose(0, 2, 1) @ grad
    U, _, Vt = np.linalg.svd(F)
    R = U @ Vt
    flip = np.linalg.det(R) < 0  # an inverted cell: keep R a proper rotation
    if np.any(flip):
        U[flip, :, -1] *= -1
        R[flip] = U[flip] @ Vt[flip]
    return R


class PronyForces:
    """The viscous (Prony) forces of every piece in a scene.

    Call :meth:`apply` once per physics step, before ``mj_step``; it updates the lagged
    displacements exactly for the step and writes the forces into ``qfrc_applied``.
    """

    def __init__(self, scene: Scene) -> None:
        m = scene.model
        self.model = m
        dt = m.opt.timestep
        node_bodies, dofs, stiff, g, decay, rest = [], [], [], [], [], []
        n_terms = max(len(p.material.prony_terms) for p in scene.pieces)
        for p, f in zip(scene.pieces, scene.piece_flex, strict=True):
            adr, num = m.flex_nodeadr[f], m.flex_nodenum[f]
            if num != 8 or m.flex_interp[f] != 1:
                raise ValueError(f"flex {f} is not a one-cell trilinear flex")
            bodies = m.flex_nodebodyid[adr : adr + num]
            node_bodies.append(bodies)
            dofs.append(np.concatenate([m.body_dofadr[b] + np.arange(3) for b in bodies]))
            k = m.flex_stiffness[m.flex_stiffnessadr[f] : m.flex_stiffnessadr[f] + 576]
            stiff.append(np.asarray(k).reshape(24, 24))
            rest.append(m.body_pos[bodies])  # node rest positions in the piece frame
            terms = list(p.material.prony_terms) + [(0.0, 1.0)] * n_terms
            terms = terms[:n_terms]
            g.append([t[0] for t in terms])
            decay.append([np.exp(-dt / t[1]) for t in terms])
        self.n_pieces = len(scene.pieces)
        self.n_terms = n_terms
        self.node_bodies = np.array(node_bodies)  # (P, 8)
        self.dofs = np.concatenate(dofs)  # (P*24,)
        self.K = np.array(stiff)  # (P, 24, 24)
        self.rest = np.array(rest)  # (P, 8, 3)
        self.grad = _centre_gradients(self.rest)
        self.g = np.array(g)  # (P, T)
        self.decay = np.array(decay)  # (P, T)
        # -g_k K, stacked per term so one einsum gives the summed force.
        self.gK = -self.g[:, :, None, None] * self.K[:, None, :, :]  # (P, T, 24, 24)
        # The same, side by side, (P, 24, T*24): one batched matmul gives the summed force.
        self._gK_row = self.gK.transpose(0, 2, 1, 3).reshape(self.n_pieces, 24, 24 * n_terms)
        self._gain = 1.0 - self.decay[:, :, None]  # (P, T, 1) weight of u in the update
        self._rest_centred = self.rest - self.rest.mean(axis=1, keepdims=True)
        self.lagged = np.zeros((self.n_pieces, n_terms, 24))
        self.active = n_terms > 0 and bool(np.any(self.g > 0))

    def reset(self, data: mujoco.MjData) -> None:
        """Start relaxed at the current configuration (no stored viscous stress)."""
        if self.n_terms:
            u, _ = self._corotated(data)
            self.lagged[:] = u[:, None, :]

    def _corotated(self, data: mujoco.MjData) -> tuple[np.ndarray, np.ndarray]:
        x = data.xpos[self.node_bodies]  # (P, 8, 3) world node positions
        x -= x.mean(axis=1, keepdims=True)  # translation-free; K ignores translation
        R = corotation(x, self.grad)
        u = (x @ R - self._rest_centred).reshape(self.n_pieces, 24)
        return u, R

    def apply(self, data: mujoco.MjData) -> None:
        """Advance the lagged displacements by one step and write the viscous forces.

        Runs every physics step, so it is written as a handful of batched matmuls (numpy's
        per-call cost, not arithmetic, dominates at these sizes).
        """
        if not self.active:
            return
        u, R = self._corotated(data)
        # Exact exponential update of du_k/dt = (u - u_k) / tau_k over the step, with u
        # held at its start-of-step value: u_k += (1 - exp(-dt/tau_k)) (u - u_k).
        lagged = self.lagged
        lagged += self._gain * (u[:, None, :] - lagged)
        f_local = self._gK_row @ lagged.reshape(self.n_pieces, -1, 1)  # (P, 24, 1)
        f_world = f_local.reshape(self.n_pieces, 8, 3) @ R.transpose(0, 2, 1)
        data.qfrc_applied[self.dofs] = f_world.reshape(-1)

    def viscous_force(self, data: mujoco.MjData, lagged: np.ndarray) -> np.ndarray:
        """The force -sum_k g_k R K u_k for given lagged displacements (for tests), (P, 8, 3)."""
        _, R = self._corotated(data)
        f_local = np.einsum("ptij,ptj->pi", self.gK, lagged).reshape(self.n_pieces, 8, 3)
        return np.einsum("pia,pba->pib", f_local, R)
