"""Food materials: elasticity, one- or multi-term Prony viscoelasticity, friction, yield.

The relaxation modulus is the Prony series
``E(t) = E_0 [1 - sum_k g_k (1 - exp(-t / tau_k))]`` with ``E_0 = young`` the instantaneous
modulus; the long-term modulus is ``E_0 (1 - sum_k g_k)``.  The study uses one term
(g_1 = 0.425, tau_1 = 3.667 s, fitted to agar gel and tempura).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field, fields, replace
from typing import Any

from fetch_env.errors import InvalidParameterError, require, require_finite

DENSITY_LIMITS = (10.0, 5e4)  # [kg/m^3] accepted densities
# Food friction coefficients are below about 2; the simulator holds up to 1000 (a fetch at
# mu 1000 runs as at 2), and 10 leaves room for an exotic coating while a typo's extra
# digits are refused before any work (at 1e100 the solver diverges mid-run).
MU_MAX = 10.0
# A relaxation time past about a day is no relaxation over any clamp; beyond 1e6 s the
# Maxwell arm's dashpot B = tau1 K2 leaves the range the estimators compute in.
TAU_MAX = 1e6  # [s]


@dataclass(frozen=True)
class Material:
    """A homogeneous viscoelastic food material (SI units).

    Attributes:
        young: instantaneous Young's modulus E_0 [Pa]; 0.0123 MPa to 200 MPa are tested.
        poisson: Poisson's ratio nu, in [0, 0.5).
        density: [kg/m^3], in ``DENSITY_LIMITS`` (10 to 5e4).
        g1, tau1: first Prony term: relative modulus drop [-] in [0, 1) and time constant [s]
            in (0, ``TAU_MAX``] (1e6).
        extra_prony: further Prony terms as ``((g_2, tau_2), ...)``; sum of all g < 1.
        mu: Coulomb friction coefficient between half-spoon and food [-], applied exactly;
            in [0, ``MU_MAX``] (10).
        plate_mu: friction coefficient between food and plate [-], in [0, ``MU_MAX``].
        yield_strain: von Mises plastic yield strain [-]; 0 means purely (visco)elastic.
        name: a label (preset name or "custom").
    """

    young: float = 0.2e6
    poisson: float = 0.3
    density: float = 1000.0
    g1: float = 0.425
    tau1: float = 3.667
    mu: float = 0.3
    plate_mu: float = 0.1
    yield_strain: float = 0.0
    extra_prony: tuple[tuple[float, float], ...] = field(default_factory=tuple)
    name: str = "custom"

    def __post_init__(self) -> None:
        for key in ("young", "poisson", "density", "g1", "tau1", "mu", "plate_mu",
                    "yield_strain"):
            require_finite(key, getattr(self, key))
        require(self.young > 0, "young", self.young, "> 0 Pa")
        require(self.young <= 1e10, "young", self.young, "<= 1e10 Pa")
        require(0 <= self.poisson < 0.5, "poisson", self.poisson, "in [0, 0.5)")
        # (foods are ~100-1500 kg/m^3; far lighter pieces fall below MuJoCo's least body mass
        # and inertia, and the simulator is checked from 10 to 5e4 kg/m^3 at 6 and 25 mm)
        require(DENSITY_LIMITS[0] <= self.density <= DENSITY_LIMITS[1], "density", self.density,
                f"in [{DENSITY_LIMITS[0]:g}, {DENSITY_LIMITS[1]:g}] kg/m^3")
        require(0 <= self.g1 < 1, "g1", self.g1, "in [0, 1)")
        require(0 < self.tau1 <= TAU_MAX, "tau1", self.tau1, f"in (0, {TAU_MAX:g}] s")
        require(0 <= self.mu <= MU_MAX, "mu", self.mu, f"in [0, {MU_MAX:g}]")
        require(0 <= self.plate_mu <= MU_MAX, "plate_mu", self.plate_mu, f"in [0, {MU_MAX:g}]")
        require(self.yield_strain >= 0, "yield_strain", self.yield_strain, ">= 0")
        require(isinstance(self.name, str), "name", self.name, "a str")
        require(isinstance(self.extra_prony, tuple | list), "extra_prony", self.extra_prony,
                "a tuple of (g, tau) pairs")
        for k, term in enumerate(self.extra_prony, start=2):
            require(isinstance(term, tuple | list) and len(term) == 2, f"extra_prony[{k - 2}]",
                    term, "a (g, tau) pair")
            g, tau = term
            require_finite(f"g{k}", g)
            require_finite(f"tau{k}", tau)
            require(0 <= g < 1, f"g{k}", g, "in [0, 1)")
            require(0 < tau <= TAU_MAX, f"tau{k}", tau, f"in (0, {TAU_MAX:g}] s")
        # Stored as a tuple of tuples whatever sequence was given: a Material is frozen and
        # hashed (scenes are cached and pieces grouped by material), which a list would break.
        object.__setattr__(self, "extra_prony",
                           tuple((g, tau) for g, tau in self.extra_prony))
        require(self.g_total < 1, "sum of Prony g", self.g_total, "< 1")

    @property
    def prony_terms(self) -> tuple[tuple[float, float], ...]:
        """All Prony terms ``((g_1, tau_1), (g_2, tau_2), ...)``; terms with g = 0 dropped."""
        terms = ((self.g1, self.tau1), *self.extra_prony)
        return tuple((g, tau) for g, tau in terms if g > 0)

    @property
    def g_total(self) -> float:
        return self.g1 + sum(g for g, _ in self.extra_prony)

    @property
    def young_long_term(self) -> float:
        """E_inf = E_0 (1 - sum g) [Pa]."""
        return self.young * (1.0 - self.g_total)

    def relaxation_modulus(self, t: float) -> float:
        """E(t) after a unit step strain at t = 0 [Pa]."""
        return self.young * (1.0 - sum(g * (1.0 - math.exp(-t / tau))
                                       for g, tau in self.prony_terms))

    def with_(self, **changes: Any) -> Material:
        """A copy with some fields changed (validated again); an unknown field is an error."""
        unknown = sorted(set(changes) - {f.name for f in fields(self)})
        require(not unknown, "Material field", unknown[0] if unknown else None,
                f"one of {[f.name for f in fields(self)]}")
        return replace(self, **changes)

    def to_dict(self) -> dict[str, Any]:
        out = asdict(self)
        out["extra_prony"] = [list(t) for t in self.extra_prony]
        return out


# The study's five stiffness levels (diced mixes: 200, 40, 5, 0.15, 0.0123 MPa) and the
# 0.2 MPa food of its viscoelastic and friction experiments.  Viscoelastic terms are the
# study's (g_1 = 0.425, tau_1 = 3.667 s) for all; friction 0.3 to the spoon, 0.1 to the plate
# (the study sets a small plate friction).
_STUDY = {"g1": 0.425, "tau1": 3.667, "mu": 0.3, "plate_mu": 0.1, "poisson": 0.3,
          "density": 1000.0}
PRESETS: dict[str, Material] = {
    "hard-200MPa": Material(young=200e6, name="hard-200MPa", **_STUDY),
    "firm-40MPa": Material(young=40e6, name="firm-40MPa", **_STUDY),
    "medium-5MPa": Material(young=5e6, name="medium-5MPa", **_STUDY),
    "soft-0.2MPa": Material(young=0.2e6, name="soft-0.2MPa", **_STUDY),
    "soft-0.15MPa": Material(young=0.15e6, name="soft-0.15MPa", **_STUDY),
    "very-soft-0.0123MPa": Material(young=0.0123e6, name="very-soft-0.0123MPa", **_STUDY),
}
STUDY_LEVELS: tuple[str, ...] = ("hard-200MPa", "firm-40MPa", "medium-5MPa", "soft-0.15MPa",
                                 "very-soft-0.0123MPa")


def preset(name: str) -> Material:
    """Look up a preset by name; the error lists the valid names."""
    if not isinstance(name, str) or name not in PRESETS:
        raise InvalidParameterError(
            f"unknown material preset {name!r}; choose from {', '.join(sorted(PRESETS))}")
    return PRESETS[name]
