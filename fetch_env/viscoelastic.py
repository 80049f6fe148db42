"""Prony-series viscoelasticity on top of MuJoCo's flex elasticity, as a moving rest shape.

MuJoCo 4 computes the elastic force of a one-cell trilinear flex as a corotational linear
element: ``f = R K (R^T x - X0)``, with ``K`` the compiled 24x24 cell stiffness
(``mjModel.flex_stiffness``, scaled by the flex's Young's modulus), ``x`` the 8 node
positions, ``X0`` the rest shape (``mjModel.flex_node0``) and ``R`` the rotation of the polar
decomposition of the deformation gradient at the cell centre.  (``tests/test_viscoelastic.py``
checks this against ``qfrc_passive`` on randomly deformed and rotated pieces.)

Because that law is linear in the corotated displacement ``u = R^T x - X0``, a standard
linear solid / Prony series is exact on the same discretization: with MuJoCo's modulus set
to the instantaneous ``E_0``, each Prony term k keeps a lagged displacement ``u_k`` with
``du_k/dt = (u - u_k) / tau_k`` (updated exactly over a step), and the total force is
``R K (u - sum_k g_k u_k)``.  At t = 0+ that is ``K u`` (E_0); once relaxed it is
``(1 - sum g_k) K u`` (E_inf); in between it follows E(t) of the Prony series.

The viscous part is applied by moving the rest shape: ``X0' = X0 + sum_k g_k u_k``, written
into ``mjModel.flex_node0``, which MuJoCo reads at every step.  An earlier version added the
same force, ``-sum_k g_k R K u_k``, to ``qfrc_applied`` instead; it is equal to first order
but it diverged: a piece released from the clamp keeps its viscous stress for seconds, and
that stress, held as a self-equilibrated pair of an explicit force and MuJoCo's implicit
elastic force, is not rotated consistently by MuJoCo's linearized step, so the free piece
spun up (its angular momentum grew 40x in one contact-free step) and blew up.  Measured on
small hard ellipsoids clamped to 0.3 rad: 15 of 18 diverged with the force, none with the
rest shape (none with the Prony terms switched off either); in 9-piece diced mixes at
0.085 rad, 5 of 24 diverged with the force and none of 36 with the rest shape.  As a moving
rest shape the released piece simply relaxes back toward its original shape, with no
stored force for MuJoCo to mis-rotate.

The rest shape belongs to this object's model and is restored by :meth:`reset` (and
:meth:`restore`), so runs stay independent and reproducible; no global MuJoCo callback is
used, so any number of simulations can run in one process.
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


class PronyRelaxation:
    """The Prony relaxation of every piece in a scene, as a moving rest shape.

    Call :meth:`reset` at the start of a run and :meth:`apply` once per physics step, before
    ``mj_step``; it updates the lagged displacements exactly for the step and moves the rest
    shape in ``mjModel.flex_node0``.  :meth:`restore` puts the compiled rest shape back.
    """

    def __init__(self, scene: Scene) -> None:
        m = scene.model
        self.model = m
        node_bodies, node_adr, dofs, stiff, g, taus = [], [], [], [], [], []
        n_terms = max(len(p.material.prony_terms) for p in scene.pieces)
        for p, f in zip(scene.pieces, scene.piece_flex, strict=True):
            adr, num = m.flex_nodeadr[f], m.flex_nodenum[f]
            if num != 8 or m.flex_interp[f] != 1:
                raise ValueError(f"flex {f} is not a one-cell trilinear flex")
            bodies = m.flex_nodebodyid[adr : adr + num]
            node_bodies.append(bodies)
            node_adr.append(adr + np.arange(num))
            dofs.append(np.concatenate([m.body_dofadr[b] + np.arange(3) for b in bodies]))
            k = m.flex_stiffness[m.flex_stiffnessadr[f] : m.flex_stiffnessadr[f] + 576]
            stiff.append(np.asarray(k).reshape(24, 24))
            terms = list(p.material.prony_terms) + [(0.0, 1.0)] * n_terms
            terms = terms[:n_terms]
            g.append([t[0] for t in terms])
            taus.append([t[1] for t in terms])
        self.n_pieces = len(scene.pieces)
        self.n_terms = n_terms
        self.node_bodies = np.array(node_bodies)  # (P, 8)
        self.node_adr = np.concatenate(node_adr)  # (P*8,) rows of flex_node0
        self.dofs = np.concatenate(dofs)  # (P*24,)
        self.K = np.array(stiff)  # (P, 24, 24), MuJoCo's sign: elastic force = R K u
        rest = np.array([m.body_pos[b] for b in node_bodies])  # (P, 8, 3) in the piece frame
        self.grad = _centre_gradients(rest)
        self.g = np.array(g)  # (P, T)
        self._g_row = self.g[:, None, :]  # (P, 1, T): one batched matmul sums g_k u_k
        self._tau = np.array(taus)[:, :, None]  # (P, T, 1) tau_k
        self.set_time_scale(1.0)
        self._pending = 0  # steps skipped while every piece slept (see apply)
        self._rest_centred = rest - rest.mean(axis=1, keepdims=True)
        self.rest0 = np.array(m.flex_node0[self.node_adr])  # the compiled rest shape
        # The per-step reads and writes use slices where the rows are contiguous (a
        # single piece's node bodies, every scene's flex nodes): a slice is cheaper
        # than a gather, and the views are fetched once.
        self._node0 = m.flex_node0
        self._node_rows = _as_slice(self.node_adr)
        self._node_xpos = _as_slice(self.node_bodies.ravel())
        self.lagged = np.zeros((self.n_pieces, n_terms, 24))
        # Each piece's rotation as a quaternion, warm-starting MuJoCo's own rotation
        # extraction (mju_mat2Rot: the iterative polar rotation MuJoCo's flexes use); from
        # the last step's rotation it converges in a few iterations, 0.7 us a call against
        # 7 us for numpy's batched SVD (agreement with the SVD: ~2e-9, tested).
        self._quat = np.tile([1.0, 0.0, 0.0, 0.0], (self.n_pieces, 1))
        self._R = np.zeros((self.n_pieces, 9))
        self.active = n_terms > 0 and bool(np.any(self.g > 0))

    def set_time_scale(self, scale: float) -> None:
        """Advance the relaxation ``scale`` physics steps' worth per step from now on.

        A quasi-static hold may be run time-scaled (see :class:`fetch_env.controller.
        TimeScale`): each step of ``dt`` then stands for ``scale * dt`` of the material's
        time (``scale`` may change from step to step).  ``scale`` 1 is the plain, physical update.
        """
        self._decay = np.exp(-scale * self.model.opt.timestep / self._tau)  # exp(-s dt / tau_k)
        self._gain = 1.0 - self._decay  # weight of u in the one-step update

    def restore(self) -> None:
        """Put the compiled rest shape back into the model."""
        self._node0[self._node_rows] = self.rest0

    def reset(self, data: mujoco.MjData) -> None:
        """Start relaxed at the current configuration (no stored viscous stress)."""
        self.restore()
        self._pending = 0
        self._quat[:] = (1.0, 0.0, 0.0, 0.0)
        if self.n_terms:
            u, _ = self._corotated(data)
            self.lagged[:] = u[:, None, :]
            self._move_rest_shape()

    def _corotated(self, data: mujoco.MjData) -> tuple[np.ndarray, np.ndarray]:
        """Corotated displacement from the compiled rest shape (P, 24), and R (P, 3, 3)."""
        xw = data.xpos[self._node_xpos].reshape(self.n_pieces, 8, 3)  # world node positions
        # translation-free (K ignores translation); the mean as np.mean computes it, without
        # its Python wrapper (this runs every step)
        x = xw - np.add.reduce(xw, axis=1, keepdims=True) / 8.0
        F = x.transpose(0, 2, 1) @ self.grad  # (P, 3, 3) deformation gradient at the centre
        quat, flat = self._quat, self._R
        for p in range(self.n_pieces):
            mujoco.mju_mat2Rot(quat[p], F[p].ravel())
            mujoco.mju_quat2Mat(flat[p], quat[p])
        R = flat.reshape(self.n_pieces, 3, 3)
        u = (x @ R - self._rest_centred).reshape(self.n_pieces, 24)
        return u, R

    def _move_rest_shape(self) -> None:
        shift = self._g_row @ self.lagged  # (P, 1, 24): sum_k g_k u_k
        self._node0[self._node_rows] = self.rest0 + shift.reshape(-1, 3)

    def apply(self, data: mujoco.MjData, asleep: bool = False) -> None:
        """Advance the lagged displacements by one step and move the rest shape.

        Runs every physics step, so it is written as a handful of batched numpy calls
        (numpy's per-call cost, not arithmetic, dominates at these sizes).

        ``asleep``: every piece is asleep (MuJoCo's sleeping islands): their nodes are frozen,
        so ``u`` is constant and the update can wait; the next awake call advances over all
        the pending steps at once with the exact decay ``exp(-k dt / tau_k)``, which is exact
        for a constant ``u``.
        """
        if not self.active:
            return
        if asleep:
            self._pending += 1
            return
        u, _ = self._corotated(data)
        # Exact exponential update of du_k/dt = (u - u_k) / tau_k over the step, with u
        # held at its start-of-step value: u_k += (1 - exp(-dt/tau_k)) (u - u_k).
        if self._pending:
            gain = 1.0 - self._decay ** (self._pending + 1)
            self._pending = 0
        else:
            gain = self._gain
        lagged = self.lagged
        lagged += gain * (u[:, None, :] - lagged)
        self._move_rest_shape()

    def viscous_force(self, data: mujoco.MjData, lagged: np.ndarray) -> np.ndarray:
        """The viscous force ``-sum_k g_k R K u_k`` the rest shift amounts to (to first
        order), for given lagged displacements, shape (P, 8, 3); for tests."""
        _, R = self._corotated(data)
        f_local = -np.einsum("pt,pij,ptj->pi", self.g, self.K, lagged)
        return np.einsum("pia,pba->pib", f_local.reshape(self.n_pieces, 8, 3), R)


def _as_slice(index: np.ndarray) -> slice | np.ndarray:
    """``index`` as a slice when it is a contiguous ascending run, else unchanged."""
    first = int(index[0])
    if np.array_equal(index, np.arange(first, first + index.size)):
        return slice(first, first + index.size)
    return index
