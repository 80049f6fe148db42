"""How closely a committed run's numbers reproduce on this machine.

The probes' estimates are least-squares fits: a difference in the last bit of one sample
moves where a fit stops, by up to tenths of a percent.  numpy chooses its ``exp``, ``log``
and ``power`` kernels by the CPU at run time, and its AVX-512 kernels (``X86_V4``) and the
AVX2 or libm ones differ in the last bit on a few per cent of inputs.  The committed runs
were written where numpy dispatched its AVX-512 kernels (AMD EPYC and Intel Xeon here):
there they reproduce bit for bit; elsewhere (a CPU without AVX-512, an ARM machine) their
estimates reproduce to :data:`OTHER_KERNELS_RTOL`.

That bound is measured, not assumed: numpy held to its AVX2 kernels
(``NPY_DISABLE_CPU_FEATURES="AVX512_ICL X86_V4"``) moved the estimates of the reporting
foods the tests re-measure by at most 0.72 % (B and tau1; K1 0.22 %, g1 0.15 %, mu not at
all), the bounds of every interval narrower than its estimate by at most 1.1 % of the
estimate (a K2 that one clamp leaves unidentified, its interval 8.6 times its estimate, by
1.8 times it), and FoodFetch-Block-v0's observations by at most 0.60 %, with every outcome
(reward, fetch rate) the same.  The simulation itself (MuJoCo) does not use numpy's kernels
and is the same on both.
"""

from __future__ import annotations

import numpy as np

#: The numpy SIMD level whose kernels wrote the committed runs.
COMMITTED_KERNELS = "X86_V4"

#: Relative agreement of an estimate with a committed run's where numpy's kernels differ
#: from :data:`COMMITTED_KERNELS` (about three times the largest difference measured).
OTHER_KERNELS_RTOL = 0.02


def simd_found() -> list[str]:
    """The SIMD levels numpy dispatches to on this machine (after ``NPY_DISABLE_CPU_FEATURES``)."""
    info = np.show_config(mode="dicts").get("SIMD Extensions", {})
    return list(info.get("found", [])) if isinstance(info, dict) else []


def kernels_match_committed() -> bool:
    """Whether numpy here dispatches the kernels the committed runs were written with."""
    return COMMITTED_KERNELS in simd_found()


def committed_rtol(same_kernels: float = 0.0) -> float:
    """The relative tolerance to hold a re-measured number to its committed value:
    ``same_kernels`` where numpy's kernels match the committed runs', else
    :data:`OTHER_KERNELS_RTOL`."""
    return same_kernels if kernels_match_committed() else OTHER_KERNELS_RTOL


def kernels_note() -> str:
    """One phrase for a report: how the committed numbers are compared here."""
    if kernels_match_committed():
        return "bit for bit"
    return (f"to {100 * OTHER_KERNELS_RTOL:g} %: numpy's kernels here ({', '.join(simd_found())})"
            f" are not the committed runs' ({COMMITTED_KERNELS})")
