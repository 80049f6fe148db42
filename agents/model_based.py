"""``model-based``: the clamp angle from the estimated food properties and the camera's sizes.

The model (SI units throughout; numbers in :class:`ModelBasedConfig`):

* **Geometry** (``fetch_env.scene.Geometry``): the half-spoons' contact faces are vertical at
  the open pose, ``gap`` from the food on each side, and rotate about a hinge
  ``hinge_height`` above the plate.  The contact section at the food's centroid height is
  ``L = hinge_height - max_height / 2`` below the hinge, so at ``theta_d`` each face presses
  ``dx = L theta_d - gap`` into the food; both faces squeeze the food's width ``w`` (the
  camera's ``span_along``, the extent along the clamp) by ``2 dx``: nominal strain
  ``eps = 2 dx / w``, predicted logarithmic strain ``LE = -ln(1 - eps)``.
* **Grip**: the relaxed normal force of the standard linear solid is ``F_n = K1 dx`` (the
  Maxwell arm K2-B has relaxed away), friction acts on both half-spoons, so the food is held
  through the lift when ``2 mu K1 dx >= SF m (g + a_lift)``, with ``a_lift`` the lift's
  acceleration (``lift_speed / lift_ramp``) and safety factor ``SF`` (default 3).
* **Engagement**: a rounded piece touches a face on a small patch, where the linear spring
  ``K1 dx`` overstates the force; in the simulator spheres and ellipsoids were held only
  from a nominal strain of about 6-13 %, so the squeeze is at least ``eps_min`` (15 %).
* **Strain limit**: the predicted LE must stay below ``margin * safe_log_strain`` (0.8 x
  0.34).  When the grip needs more than that, the agent goes at most to
  ``safe_log_strain + overshoot`` (an LE overshoot of 0.1 costs 0.5 reward; a dropped piece 1).
* **Clamp speed and lift** from K2 and B: the Maxwell arm relaxes with ``tau1 = B / K2``; the
  settling time ``t_s = tau1 ln(g1 / ((1 - g1) tol))`` is when the moment is within ``tol``
  of its relaxed value.  The clamp is slowed when the instantaneous moment
  ``L dx (K1 + K2 phi)`` (phi: the Maxwell arm's share left after a clamp of duration T)
  would approach the motor's stall moment; the lift runs at a speed that ends it at
  ``t_s`` (between ``lift_speed_min`` and ``lift_speed_max``), so the food is in the air
  when the grip has settled on the relaxed force the grip rule was designed for.
* **Time cost** (the -v1 ids' ``time_weight``, read from the env at ``begin_episode``, or
  ``ModelBasedConfig.time_weight``): the grip rule already uses the relaxed force K1, the
  least the food pushes back with, so waiting for it to settle buys no grip.  When time
  costs, the agent clamps at ``omega_fast`` (still slowed near the motor's stall) and lifts
  at ``lift_speed_fast``, with the lift's acceleration in the grip rule.

* **Layout** (read from the env at ``begin_episode``, as an RL Zoo file keeps hyperparameters
  per id): a two-row plate (``layout="two_rows"``) is a grid of equal cubes, two in series
  along the clamp with a 1 mm gap between them, so the blades hold the pair once that gap has
  closed, with little squeeze, and a deeper squeeze of soft cubes in series tears them in the
  lift.  There the grip rule above does not apply (the pair is held by the closed gap, not by
  the squeeze of one piece) and the squeeze is ``eps_min_two_rows`` of the span
  (``FIXED_SQUEEZE_LAYOUTS``; chosen on tuning seeds 100-139 of FoodFetch-TwoRows-v1,
  docs/agents.md; on FoodFetch-TwoRows-v0 it scores 1.000 on the ten scenes from seed 70000,
  as the grip rule did).  A diced plate (``layout="diced"``) mixes shapes and the study's
  five stiffnesses, and only its centre piece is probed, so the grip rule sizes the squeeze
  for a piece that says little about the softest die beside it; there the squeeze is
  ``eps_diced`` of the span.  On a diced mix the outcome of one squeeze is close to a lottery
  (whether a soft die is caught at the edge of the blade), so the value is the least squeeze
  whose mean reward is within the paired 95 % interval of the best one's, on a grid of
  squeezes at the fast speeds over the 200 tuning scenes (seeds 100-299) of
  FoodFetch-Diced-v1 (``benchmarks/squeeze_grid.py``, docs/agents.md): 10 % of the span
  scored as the grip rule on average with half the spread of its rewards, where 15 and 18 %
  scored a little higher on average with 17 and 27 badly crushed plates against its 6.
  For the same reason the clamp on a diced plate (``MIXED_LAYOUTS``) is not slowed for the
  probed piece's predicted moment: on those tuning scenes the slowed clamp scored lower on
  every one of the 18 plates where it applied.
  A two-row plate of any shape (FoodFetch-TwoRows-v3, ``scenes="any_shape_two_rows"``,
  ``FIXED_DEPTH_SCENES``) is squeezed a fixed depth per face whatever its span: a round
  piece is held only once the faces reach nearer its equator, 2.5 mm
  (``dx_any_shape_two_rows``), and cubes, held at their bottom edges, 1.2 mm
  (``dx_any_shape_two_rows_cubes``); the pieces are cubes when the plate's mass is at least
  ``cube_fill`` of ``n size^3`` at 1050 kg/m^3 (cubes fill 0.91-1.09 of it on the tuning
  plates, spheres and ellipsoids at most 0.56).  On the 40 tuning plates (seeds 100-139,
  ``benchmarks/theta_sweep.py``; each depth's angle read off the sweep's grid) the depths
  within 0.05 of each plate's best are 1.5-2.7 mm or wider for the round plates and
  0.9-2.3 mm or wider for the cubes, so the rule is near the best on all 40 (0.894 against
  the per-scene best's 0.898), where no share of the span is (0.20 of it misses one plate).
  One depth for both, 2.5 mm, was as good on the grid but pressed a plate of 20 mm,
  0.15 MPa cubes to 0.097 rad, between two grid angles, where the simulation flung it apart.

Fallbacks: when the viscoelastic estimate is invalid (flag 0) K1, K2, B come from a cautious
prior (the softest food-like modulus, 0.05 MPa, and the largest g1); an invalid mu is taken
as the lowest (0.15).  With no estimates at all the agent is then a geometry-only rule.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import Any, NamedTuple

import numpy as np

from agents.base import Agent
from fetch_env.env import ACTION_RANGES, decode_observation, physical_to_action
from fetch_env.scene import Geometry

G = 9.81  # [m/s^2]


@dataclass(frozen=True)
class ModelBasedConfig:
    safety_factor: float = 3.0  # on the weight plus lift inertia
    eps_min: float = 0.15  # minimum nominal squeeze (engagement of rounded pieces)
    safe_log_strain: float = 0.34  # the study's no-large-deformation level
    strain_margin: float = 0.8  # predicted LE kept below margin * safe level
    overshoot: float = 0.1  # at most this much LE above the safe level when grip needs it
    lift_ramp: float = 0.05  # [s] time the lift takes to reach its speed
    settling_tolerance: float = 0.1  # t_s: relaxing part within this share of the relaxed
    omega: float = 0.1  # [rad/s] clamp speed when the motor is far from stall
    omega_min: float = 0.02  # [rad/s]
    stall_moment: float = 2.0  # [N m] the clamping motor's stall
    stall_margin: float = 1.0  # keep the predicted peak moment below this share of stall
    lift_speed_min: float = 0.004  # [m/s]
    lift_speed_max: float = 0.02  # [m/s]
    lift_height: float = 0.005  # [m] the env's default lift
    hold: float = 0.5  # [s] the env's default hold before lifting
    prior_young: float = 0.05e6  # [Pa] softest food-like modulus (fallback K1)
    prior_g1: float = 0.6  # largest g1 (fallback: most relaxation)
    prior_tau1: float = 3.0  # [s]
    prior_mu: float = 0.15  # lowest mu (fallback)
    time_weight: float | None = None  # [1/s] the reward's time cost; None: the env's
    omega_fast: float = 0.4  # [rad/s] clamp speed when time costs (the action's fastest)
    lift_speed_fast: float = 0.04  # [m/s] lift speed when time costs (the action's fastest)
    eps_min_two_rows: float = 0.07  # nominal squeeze of a two-row plate's span
    eps_diced: float = 0.10  # nominal squeeze of a diced plate's span
    dx_any_shape_two_rows: float = 0.0025  # [m] squeeze per face of a round two-row plate
    dx_any_shape_two_rows_cubes: float = 0.0012  # [m] the same for a plate of cubes
    cube_fill: float = 0.75  # mass over (n size^3 x 1050 kg/m^3) from which pieces are cubes
    layout: str | None = None  # the scene family; None: the env's, read at begin_episode
    scenes: str | None = None  # the scene space; None: the env's, read at begin_episode


# Layouts whose squeeze is a fixed share of the span instead of the grip rule's (see the
# module docstring), with the config field that holds the share.
FIXED_SQUEEZE_LAYOUTS: dict[str, str] = {"two_rows": "eps_min_two_rows", "diced": "eps_diced"}
# Layouts whose probed piece does not stand for the pieces the blades close on: the clamp is
# not slowed for the probed piece's predicted moment.
MIXED_LAYOUTS: frozenset[str] = frozenset({"diced"})
# (layout, scene space) pairs whose squeeze is a fixed depth per face, with the config fields
# that hold it for round pieces and for cubes (see the module docstring)
FIXED_DEPTH_SCENES: dict[tuple[str, str], tuple[str, str]] = {
    ("two_rows", "any_shape_two_rows"): ("dx_any_shape_two_rows",
                                         "dx_any_shape_two_rows_cubes")}


class _Food(NamedTuple):
    """The food model the plan works with: SLS springs [N/m], friction, Prony terms."""

    k1: float
    k2: float
    mu: float
    tau1: float
    g1: float
    visco_ok: bool
    fric_ok: bool


FOOD_DENSITY = 1050.0  # [kg/m^3] the middle of the scenes' densities, for the cube test


class ModelBasedAgent(Agent):
    """Smallest clamp angle that grips with a margin and keeps the strain safe (see module)."""

    name = "model-based"

    def __init__(self, config: ModelBasedConfig | None = None,
                 geometry: Geometry | None = None) -> None:
        super().__init__()
        self.config = config or ModelBasedConfig()
        self.geometry = geometry or Geometry()
        self.last_plan: dict[str, Any] = {}
        self.time_weight = self.config.time_weight or 0.0
        self.layout = self.config.layout
        self.scenes = self.config.scenes

    def begin_episode(self, env: Any) -> None:
        """Read the reward's time cost, the layout and the scene space from the env unless
        the config fixes them."""
        if self.config.time_weight is None:
            self.time_weight = float(getattr(env.unwrapped, "time_weight", 0.0))
        if self.config.layout is None:
            layout = getattr(env.unwrapped, "layout", None)
            self.layout = layout if isinstance(layout, str) else None
        if self.config.scenes is None:
            scenes = getattr(env.unwrapped, "scenes", None)
            self.scenes = scenes if isinstance(scenes, str) else None

    # ----------------------------------------------------------------- the model
    def plan(self, obs: np.ndarray) -> dict[str, Any]:
        """The physical action and the numbers behind it (also kept as ``last_plan``).

        In phases: the food's model (the estimates, or the prior where they are invalid),
        the lift speed, the squeeze per face and its clamp angle, then the clamp speed."""
        c, geo = self.config, self.geometry
        d = decode_observation(obs)
        height = float(d["max_height"])
        w = float(d["span_along"]) if d["span_along"] > 0 else float(d["mean_size"])
        L = lever(geo, height)
        # Mass held: all the pieces (conservative for a mix, where some may escape).
        mass = float(d["total_mass"])
        food = self._food_model(d, height, w)
        lift_speed, t_s = self._lift_speed(food)
        a_lift = lift_speed / c.lift_ramp
        # Grip: 2 mu K1 dx >= SF m (g + a)  ->  the smallest squeeze per face.
        dx_grip = c.safety_factor * mass * (G + a_lift) / (2.0 * food.mu * food.k1)
        eps_grip = 2.0 * dx_grip / w
        dx, eps, limited = self._squeeze(d, w, mass, eps_grip)
        lo, hi = ACTION_RANGES["theta_d"]
        theta = float(np.clip(clamp_angle(geo, height, dx), lo, hi))
        omega, m_peak = self._clamp_speed(theta, L, dx, food)
        slo, shi = ACTION_RANGES["lift_speed"]
        lift_speed = float(np.clip(lift_speed, slo, shi))
        le_pred = -math.log(max(1.0 - eps, 1e-9))
        self.last_plan = {
            "theta_d": theta, "omega": omega, "lift_speed": lift_speed, "L": L, "width": w,
            "dx": dx, "eps": eps, "eps_grip": eps_grip, "le_pred": le_pred,
            "grip_margin": 2.0 * food.mu * food.k1 * dx / (mass * (G + a_lift)),
            "t_s": t_s, "m_peak": m_peak, "visco_valid": food.visco_ok,
            "friction_valid": food.fric_ok, "limited": limited}
        return self.last_plan

    def _food_model(self, d: dict[str, Any], height: float, w: float) -> _Food:
        """K1, K2, B, mu (and tau1, g1) from the estimates, or from the prior where a flag
        says an estimate is invalid."""
        c = self.config
        visco_ok = bool(d["visco_valid"] >= 0.5 and math.isfinite(d["K1"]) and d["K1"] > 0)
        fric_ok = bool(d["friction_valid"] >= 0.5 and math.isfinite(d["mu"]) and d["mu"] > 0)
        if visco_ok:
            k1, k2, b = float(d["K1"]), float(d["K2"]), float(d["B"])
        else:  # nominal K = 2 E A / l: face area A ~ size x height, l = the width w
            k = 2.0 * c.prior_young * float(d["mean_size"]) * height / w
            k2 = c.prior_g1 * k
            k1, b = k - k2, c.prior_tau1 * k2
        mu = float(d["mu"]) if fric_ok else c.prior_mu
        tau1 = b / k2 if k2 > 0 else c.prior_tau1
        g1 = k2 / (k1 + k2) if (k1 + k2) > 0 else c.prior_g1
        return _Food(k1, k2, mu, tau1, g1, visco_ok, fric_ok)

    def _lift_speed(self, food: _Food) -> tuple[float, float]:
        """The lift speed [m/s] that finishes the lift at the settling time t_s, or at once
        when time costs (see the module docstring), and t_s [s]."""
        c = self.config
        ratio = food.g1 / max((1.0 - food.g1) * c.settling_tolerance, 1e-9)
        t_s = food.tau1 * math.log(max(ratio, 1.0))
        t_lift = max(t_s - c.hold, 1e-3)
        lift_speed = float(np.clip(c.lift_height / t_lift, c.lift_speed_min, c.lift_speed_max))
        return (c.lift_speed_fast if self.time_weight > 0 else lift_speed), t_s

    def _squeeze(self, d: dict[str, Any], w: float, mass: float, eps_grip: float
                 ) -> tuple[float, float, str]:
        """The squeeze per face dx [m], its strain of the width and why it was limited
        ("" where it was not): a fixed depth or share of the span where the scene family
        has one, else the grip's squeeze within the safe strain."""
        c = self.config
        eps_safe = 1.0 - math.exp(-c.strain_margin * c.safe_log_strain)
        eps_cap = 1.0 - math.exp(-(c.safe_log_strain + c.overshoot))
        fixed_field = FIXED_SQUEEZE_LAYOUTS.get(self.layout or "")
        depth_fields = FIXED_DEPTH_SCENES.get((self.layout or "", self.scenes or ""))
        limited = ""
        if depth_fields is not None:
            # a cube fills its size cubed; a sphere about half of it, an ellipsoid less
            fill = mass / max(float(d["n_pieces"]) * float(d["mean_size"]) ** 3 * FOOD_DENSITY,
                              1e-12)
            eps = 2.0 * float(getattr(c, depth_fields[fill >= c.cube_fill])) / w
        elif fixed_field is not None:
            eps = min(float(getattr(c, fixed_field)), eps_safe)
        else:
            eps = max(eps_grip, c.eps_min)
            if eps > eps_safe:
                limited = "grip needs more squeeze than the safe strain"
                eps = max(min(eps_grip, eps_cap), eps_safe)
        dx = eps * w / 2.0
        return dx, eps, limited

    def _clamp_speed(self, theta: float, L: float, dx: float, food: _Food
                     ) -> tuple[float, float]:
        """The clamp speed [rad/s] that keeps the instantaneous moment L dx (K1 + K2 phi)
        below the stall, halved at most eight times, and that peak moment [N m]."""
        c = self.config
        omega = c.omega_fast if self.time_weight > 0 else c.omega
        stall = c.stall_margin * c.stall_moment
        # Slowing down relaxes only the Maxwell arm: where the relaxed moment L dx K1 alone
        # passes the stall, a slower clamp stalls all the same and, when time costs, only
        # costs time.
        hopeless = self.time_weight > 0 and L * dx * food.k1 > stall
        # On a mix the probed piece's stiffness does not predict the moment of the pieces
        # between the blades (see the module docstring), so the clamp is not slowed for it.
        keep_speed = hopeless or self.layout in MIXED_LAYOUTS
        for _ in range(8):
            m_peak = L * dx * (food.k1 + food.k2 * _maxwell_share(theta / omega, food.tau1))
            if m_peak <= stall or omega <= c.omega_min or keep_speed:
                break
            omega = max(omega / 2.0, c.omega_min)
        olo, ohi = ACTION_RANGES["omega"]
        return float(np.clip(omega, olo, ohi)), m_peak

    def act(self, obs: np.ndarray) -> np.ndarray:
        p = self.plan(obs)
        return physical_to_action(p["theta_d"], p["omega"], p["lift_speed"])

    def describe(self) -> dict[str, Any]:
        return {"name": self.name, **asdict(self.config)}


def lever(geometry: Geometry, max_height: float) -> float:
    """L [m]: the hinge's height over the food's mid-height, where each face presses in."""
    return geometry.hinge_height - max_height / 2


def face_squeeze(geometry: Geometry, max_height: float, theta_d: Any) -> Any:
    """dx [m]: how far each face presses into the food at ``theta_d`` [rad] (array or float)."""
    return lever(geometry, max_height) * theta_d - geometry.gap


def clamp_angle(geometry: Geometry, max_height: float, dx: float) -> float:
    """theta_d [rad] at which each face presses ``dx`` [m] into the food."""
    return (geometry.gap + dx) / lever(geometry, max_height)


def _maxwell_share(duration: float, tau1: float) -> float:
    """The Maxwell arm's share of its force left after a ramp of ``duration`` [s]:
    ``phi = tau1 / T (1 - exp(-T / tau1))`` (1 for an instant clamp)."""
    if duration <= 0:
        return 1.0
    return tau1 / duration * (1.0 - math.exp(-duration / tau1))
