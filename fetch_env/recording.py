"""The per-sample meters of a run, computed over batches of samples.

Each meter (the strain per element, the blade overlap, the lowest vertex, the split of the
blades' contact force) is a dozen numpy calls on a few hundred numbers.  Run between two
``mj_step`` calls they cost far more than their arithmetic (numpy's per-call cost, from
caches the step has just evicted): in a single-cube fetch they added ~100 us to each ~400 us
step (the fetch's wall time over its own ``mj_step`` time was 1.31, and 1.13 with them
stubbed out).  So the loop only copies each sample's raw state (a few numpy
calls), and the meters run over a chunk of samples at once.
"""

from __future__ import annotations

import mujoco
import numpy as np

from fetch_env.metrics import BladeOverlap, PiecePositions, StrainMeter
from fetch_env.scene import Scene
from fetch_env.sensors import ContactSensors

# Metered samples of vertex positions held before the meters run over them: this bounds the
# memory of a long run (a 9-piece mix has ~450 vertices, ~11 kB a sample).
CHUNK = 256


class TraceRecorder:
    """Records one run's samples: raw state in the loop, the meters in batches.

    At every recorded sample :meth:`sample` copies the sensors' raw numbers; at a metered
    sample also the vertex positions and the blades' poses, which the strain, blade overlap
    and lowest-vertex meters read.  A sample that is not metered (the time-scaled hold's
    in-between steps) holds the last metered sample's values, and a metered sample whose
    strain is not fresh (nothing moved: every piece asleep) holds the last fresh strain.
    :meth:`finish` returns the traces.
    """

    def __init__(self, scene: Scene, data: mujoco.MjData, n_samples: int) -> None:
        self.strain = StrainMeter(scene, data)
        self.overlap = BladeOverlap(scene)
        self.positions = PiecePositions(scene)
        self.sensors = ContactSensors(scene)
        self._copy_sensors = self.sensors.copier(data)
        # views into MjData, fetched once
        self._xpos, self._geom_xpos, self._geom_xmat = (data.flexvert_xpos, data.geom_xpos,
                                                        data.geom_xmat)
        n_pieces = len(scene.pieces)
        self._verts = np.empty((CHUNK, *self._xpos.shape))
        self._blade_pos = np.empty((CHUNK, 2, 3))
        self._blade_mat = np.empty((CHUNK, 2, 9))
        self._fresh = np.zeros(CHUNK, dtype=bool)
        self._raw = np.empty((n_samples, ContactSensors.RAW_SIZE))
        self._overlap = np.empty(n_samples)  # per metered sample: the deepest vertex
        self._strain = np.empty((n_samples, n_pieces))  # per fresh strain sample
        self._metered_of = np.empty(n_samples, dtype=np.intp)  # sample -> its metered sample
        self._fresh_of = np.empty(n_samples, dtype=np.intp)  # sample -> its fresh strain sample
        # per piece, over the samples so far: the lowest vertex (plate pass-through) and the
        # deepest reach into a blade (blade pass-through)
        self.lowest_z = np.full(n_pieces, np.inf)
        self.max_overlap = np.zeros(n_pieces)
        self._n = self._n_metered = self._n_fresh = self._chunk = 0

    def sample(self, metered: bool, fresh_strain: bool) -> None:
        """Record the state now as the next sample.

        ``metered``: copy what the strain, overlap and lowest-vertex meters read (the first
        sample must be metered); ``fresh_strain``: (metered samples only) the strain may have
        changed since the last fresh one (the first sample must be fresh).
        """
        n = self._n
        self._copy_sensors(self._raw[n])
        if metered:
            k = self._chunk
            self._verts[k] = self._xpos
            geoms = self.overlap.geoms
            np.take(self._geom_xpos, geoms, axis=0, out=self._blade_pos[k], mode="clip")
            np.take(self._geom_xmat, geoms, axis=0, out=self._blade_mat[k], mode="clip")
            self._fresh[k] = fresh_strain
            self._n_metered += 1
            self._n_fresh += fresh_strain
            self._chunk = k + 1
            if self._chunk == CHUNK:
                self._meter_chunk()
        self._metered_of[n] = self._n_metered - 1
        self._fresh_of[n] = self._n_fresh - 1
        self._n = n + 1

    def _meter_chunk(self) -> None:
        """Run the meters over the metered samples held, and start a new chunk."""
        k = self._chunk
        if k == 0:
            return
        verts = self._verts[:k]
        overlap = self.positions.piece_max(self.overlap.of(verts, self._blade_pos[:k],
                                                           self._blade_mat[:k]))  # (k, P)
        self._overlap[self._n_metered - k:self._n_metered] = overlap.max(axis=1)
        np.maximum(self.max_overlap, overlap.max(axis=0), out=self.max_overlap)
        np.minimum(self.lowest_z, self.positions.lowest_of(verts).min(axis=0), out=self.lowest_z)
        fresh = self._fresh[:k]
        n_new = int(np.count_nonzero(fresh))
        if n_new:
            self._strain[self._n_fresh - n_new:self._n_fresh] = self.strain.piece_strain_of(
                verts[fresh])
        self._chunk = 0

    def finish(self) -> tuple[dict[str, np.ndarray], np.ndarray, np.ndarray]:
        """The traces of the samples recorded: the sensor readings
        (:meth:`ContactSensors.readings`), the blade overlap (S,) and each piece's LE (S, P).
        """
        self._meter_chunk()
        n = self._n
        if n and (self._metered_of[0] < 0 or self._fresh_of[0] < 0):
            raise ValueError("the first sample of a run must be metered, with fresh strain")
        return (self.sensors.readings(self._raw[:n]), self._overlap[self._metered_of[:n]],
                self._strain[self._fresh_of[:n]])
