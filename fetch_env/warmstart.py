"""Where MuJoCo's Newton solver starts each step: the last step's accelerations (MuJoCo's
own warm start), or, where they have been alternating from step to step, the step's before
them.

A round, stiff food held between blades whose contact is far stiffer than the step (the
``precise`` probes' relaxation clamp: a 1 ms step, impratio 1e4, the blades' contact ~300
times the default's) rings at the step's own period: the accelerations flip every step
while the held moment barely moves.  On the slowest reporting food (a 13.5 mm, 3.95 MPa
ellipsoid) ``|qacc - qacc(i-1)|`` averages twice ``|qacc|`` over the hold, and
``|qacc - qacc(i-2)|`` is 6-45 times smaller than it.  Started from the last step's
accelerations, the worst guess there, Newton takes 26 iterations a step over its seven
clamps (20-40 line-search evaluations each); started from the step before last where the
steps alternate, 13.5, and the clamps take 0.56x the CPU (7.9 s against 14.2 s, one
sitting).

The problem the solver minimises is convex with a unique minimum, so the start moves the
answer only within the solver's tolerance (1e-10), which a clamp chaotic in its squeeze
carries on as it carries any other difference (``docs/estimator_validation.md``).  Where
the steps do not alternate, MuJoCo's start is kept and the run is bit for bit MuJoCo's.
The switch's constants were set on the first 40 tuning foods (one clamp each): 23 never
switched, four stiff round pieces took 0.35-0.74x the iterations, the rest within 6 % (the
most, +0.7 %).  Deciding on the last three steps alone took 17-34 % more iterations on four
soft pieces whose contacts ring without a period, and a ratio of 0.5 instead of 0.25 48 %
more on one.
"""

from __future__ import annotations

from typing import Literal

import mujoco
import numpy as np

from fetch_env.errors import require

Warmstart = Literal["previous", "alternating"]
WARMSTARTS: tuple[str, ...] = ("previous", "alternating")


def check_warmstart(name: str, value: object) -> None:
    """Refuse a warm start that is not one of :data:`WARMSTARTS`, naming ``name``."""
    require(isinstance(value, str) and value in WARMSTARTS, name, value, f"one of {WARMSTARTS}")


class AlternatingWarmstart:
    """Before each step, start the solver from the accelerations two steps back where the
    recent steps alternated; after it, remember the step's accelerations.

    "Alternated": over the last steps (an exponential average with weight ``SMOOTHING``),
    the accelerations two steps back predicted each step's with less than ``RATIO`` times
    the squared error of the last step's.

    Call :meth:`before_step` just before ``mujoco.mj_step`` and :meth:`after_step` just
    after it, on the same ``MjData``, every step.
    """

    SMOOTHING = 0.2
    RATIO = 0.25

    def __init__(self, nv: int) -> None:
        self._history = np.zeros((3, nv))  # ring buffer of the last three qacc
        self._steps = 0
        self._err_lag1 = 0.0  # averaged squared error of the last step's qacc as a guess
        self._err_lag2 = 0.0  # of the step before last's

    def before_step(self, d: mujoco.MjData) -> None:
        """Set ``d.qacc_warmstart`` to the step before last's qacc where they alternate."""
        if self._steps >= 3 and self._err_lag2 < self.RATIO * self._err_lag1:
            d.qacc_warmstart[:] = self._history[(self._steps - 2) % 3]

    def after_step(self, d: mujoco.MjData) -> None:
        """Remember the step's accelerations and how well each lag would have guessed them."""
        n = self._steps
        self._history[n % 3] = d.qacc
        if n >= 2:
            newest = self._history[n % 3]
            lag1 = newest - self._history[(n - 1) % 3]
            lag2 = newest - self._history[(n - 2) % 3]
            a = self.SMOOTHING
            self._err_lag1 += a * (float(lag1 @ lag1) - self._err_lag1)
            self._err_lag2 += a * (float(lag2 @ lag2) - self._err_lag2)
        self._steps += 1
