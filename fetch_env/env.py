"""Gymnasium environments: one fetch attempt per episode, with probe-estimated food properties.

``FoodFetchEnv`` is the general class (``layout=`` picks the scene family); the registered ids
use the per-layout subclasses below, whose docstrings are the reference for each id.
Helpers for agents (all importable from ``fetch_env.env``): ``ACTION_RANGES``,
``action_to_physical``, ``physical_to_action``, ``OBS_NAMES``, ``OBS_SCALE``,
``OBS_TRANSFORM``, ``decode_observation``.
"""

from __future__ import annotations

import dataclasses
import math
import os
import sys
import time
from collections import OrderedDict
from collections.abc import Callable
from typing import TYPE_CHECKING, Any, ClassVar

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from fetch_env import clipping
from fetch_env.controller import FetchAction, FetchSimulator, SimResult, fetch_hold_time_scale
from fetch_env.env_scenes import (
    ANY_SHAPE_SAMPLING,
    ANY_SHAPE_TWO_ROWS_SAMPLING,
    LAYOUTS,
    RESOLVED_SAMPLING,
    SAMPLING,
    SCENE_PRESETS,
    SCENE_SPACES,
    WIDE_SAMPLING,
    layout_features,
    preset_scene,
    sample_scene,
)
from fetch_env.errors import (
    InvalidParameterError,
    SimulationDivergedError,
    check_annotated,
    check_reset,
    require,
)
from fetch_env.layouts import Piece
from fetch_env.probes import (
    PARAM_NAMES,
    PROBE_PRESETS,
    ProbeConfig,
    ProbeOutcome,
    calibration_for,
    probe_piece_index,
    run_probes,
    true_parameters,
    true_parameters_exact,
)
from fetch_env.render import EpisodeRenderer
from fetch_env.rewards import DAMAGE_MODES, damage_excess, fetch_duration
from fetch_env.scene import Geometry
from fetch_env.spaces import (
    ACTION_NAMES,
    ACTION_RANGES,
    OBS_BOUND,
    OBS_NAMES,
    OBS_SCALE,
    OBS_TRANSFORM,
    OBS_UNITS,
    Traces,
    action_to_physical,
    clip_action,
    decode_observation,
    encode_observation,
    end_stop_records,
    physical_to_action,
    theta_d_cap,
)

if TYPE_CHECKING:
    from estimators.calibration import Calibration

__all__ = [
    "ACTION_NAMES",
    "ACTION_RANGES",
    "ESTIMATORS",
    "OBS_NAMES",
    "OBS_SCALE",
    "OBS_TRANSFORM",
    "OBS_UNITS",
    "FoodFetchBlockEnv",
    "FoodFetchDicedEnv",
    "FoodFetchEnv",
    "FoodFetchRowEnv",
    "FoodFetchTwoRowsEnv",
    "action_to_physical",
    "decode_observation",
    "physical_to_action",
]

ESTIMATORS: tuple[str, ...] = ("model", "oracle", "none")
# How info["true_params"] (and the oracle) define K1, K2 and B: the nominal 2 E A / l, or
# the stiffness of the piece's purely elastic twin under the env's probe, the definition
# the estimators are validated and calibrated against (fetch_env.probes.elastic_stiffness).
TRUE_STIFFNESS: tuple[str, ...] = ("nominal", "elastic_twin")
# The reward and scene arguments that differ between versions (the ids' defaults).
VERSION_DEFAULTS: dict[str, dict[str, Any]] = {
    "v0": {"time_weight": 0.0, "damage": "worst", "scenes": "study"},
    "v1": {"time_weight": 0.1, "damage": "per_piece", "scenes": "wide"},
    "v2": {"time_weight": 0.1, "damage": "per_piece", "scenes": "resolved"},
}
# The sampling table each scene space's docstring lists.
_SPACE_SAMPLING: dict[str, dict[str, dict[str, Any]]] = {
    "study": SAMPLING, "wide": WIDE_SAMPLING, "resolved": RESOLVED_SAMPLING,
    "any_shape": ANY_SHAPE_SAMPLING, "any_shape_two_rows": ANY_SHAPE_TWO_ROWS_SAMPLING}
RESET_OPTIONS: tuple[str, ...] = ("preset", "pieces")
_CACHE_SIZE = 8  # compiled scenes (and probe outcomes) kept per env, least recently used out


class _LRU(OrderedDict):
    def get_or(self, key: Any, make: Any) -> Any:
        if key in self:
            self.move_to_end(key)
            return self[key]
        value = self[key] = make()
        while len(self) > _CACHE_SIZE:
            self.popitem(last=False)
        return value


_COMMON_DOC = """
    ## Action space
    ``Box(-1, 1, (3,), float32)``, mapped linearly onto (values outside [-1, 1] are clipped,
    reported in ``info["clipped"]``; NaN, infinities or another shape raise
    ``InvalidParameterError``):

    | index | name | low | high | unit | meaning |
    |---|---|---|---|---|---|
    | 0 | theta_d | {theta_d[0]} | {theta_d[1]} | rad | clamp angle from the open pose |
    | 1 | omega | {omega[0]} | {omega[1]} | rad/s | clamping angular velocity |
    | 2 | lift_speed | {lift_speed[0]} | {lift_speed[1]} | m/s | lifting speed |

    ``action_to_physical(a)`` and ``physical_to_action(theta_d, omega, lift_speed)`` convert.
    theta_d is capped just short of the angle at which the half-spoons' tips meet for the
    scene (``info["action_applied"]`` has what was run, ``info["clipped"]`` says so).

    ## Observation space
    ``Box(-{bound}, {bound}, ({n_obs},), float32)``. Feature ``i`` is ``value / scale`` (linear) or
    ``log10(value / scale)`` (log10); ``decode_observation(obs)`` returns SI values (NaN for
    parameters whose flag is 0). K1..tau1 and mu are the probed piece's (the piece nearest
    the layout's centre); the rest is what a camera over the plate tells.

    | index | name | transform | scale | unit |
    |---|---|---|---|---|
{obs_table}

    ``estimator="model"``: K1, K2, B, g1, tau1 from the hold alone
    (``estimators.estimate_from_hold``, past ``probes.HOLD_SETTLE``, with the contact angle of
    ``estimators.estimate_full_fit``, or of ``estimate_three_step``), on the moment of a reset
    probe (clamp at ``probe_omega`` to ``probe_strain`` past first contact, hold
    ``probe_hold``), mu from an induced-slip probe (``estimators.estimate_friction``, or the
    upper envelope of the force ratio when the blades stick-slip; ``fetch_env.probes``); a
    failed estimate gives 0 and a cleared flag. ``"oracle"``: the true values (g1, tau1, mu
    of the material exactly; K1, K2, B as ``true_stiffness`` defines them: nominal,
    ``K = 2 E A / l`` split by g1, see ``fetch_env.probes.nominal_stiffness``, or with
    ``true_stiffness="elastic_twin"`` the stiffness of the piece's purely elastic twin held
    by the env's relaxation probe, ``fetch_env.probes.elastic_stiffness``: what an exact
    estimator returns for this piece, shape and clamp, the truth the estimators are
    validated and calibrated against; it costs a clamp of the twin, 1.6x a Block reset's CPU
    time, measured on 24 held-back scenes, where the model's K1 is then 3.6 % off at the median
    against 19.6 % from the nominal stiffness on the study's scenes, 10 % against 16 % on
    the wide ones).
    ``"none"``: zeros, flags 0 (the ablation).
    With the default probe settings the model's estimates are calibrated
    (``probe_calibrated=True``; ``estimators.calibration``): a correction of the probes'
    systematic errors (the contact in series with the food, friction at the faces) fitted on
    reference foods of the food space that no environment draws from
    (``fetch_env.food_space.TUNING_SEED``), as an instrument is calibrated against reference
    samples; ``docs/estimator_validation.md`` has what it does on other foods.
    The hold must be of the order of tau1 (1 to 6 s) to separate g1 from tau1.  The default
    ``probe_hold`` of 6 s is simulated quasi-statically time-scaled: past its first
    ``probes.HOLD_SETTLE`` the blades stand still and only the food relaxes, so each physics
    step stands for at least ``probe_time_scale=8`` steps and for at least
    ``probe_time_growth=0.05`` of the hold's elapsed time (log-spaced, as a relaxation test
    records; ``fetch_env.controller.TimeScale``): 6 s of relaxation in ~60 steps.  With the
    probes' other settings (``fetch_env.probes.ProbeConfig``) it costs about a third of a
    Block episode; the accuracy on held-back scenes is in the README and
    ``docs/validation/probes.md``.  ``probes="measure"`` runs the one-clamp probes of
    ``food-fetch estimate --probes measure`` instead (a 20 s hold, a 0.3 s slide;
    ``fetch_env.probes.PROBE_PRESETS``), with their own calibration, and on Block scenes of
    the study space with the one fitted on 256 such scenes
    (``fetch_env.probes.calibration_for``): on the 64 held-back Block scenes g1, tau1 and mu
    are within 1.1, 1.6 and 0.1 % (median; 95th percentile 3.4, 7.2 and 1.8 %), against
    the default probes' 1.3, 3.0 and 0.1 % (6.7, 15.9 and 6.2 %), for 1.37x the reset's
    CPU time; ``probes="repeated"`` (seven clamps, K1, K2 and B at the depth camera's
    contact angle, the food space's quadratic calibration) gives g1 0.8 / 2.5 % and tau1
    1.4 / 5.8 %, for 6.1x (``docs/estimator_validation.md``); ``probes="precise"`` runs
    ``food-fetch estimate``'s probes (repeated's at a 1 ms step, nearly rigid friction and a
    much stiffer blade contact; several seconds a reset).
    ``probe_time_scale=1, probe_time_growth=0`` simulates the hold in real time (the unscaled
    reference); ``probe_hold=0.3`` still gives mu but g1 and tau1 only coarsely or not at
    all.

    ## Rewards
    ``reward = reward_fetch + reward_deformation + reward_time`` (each in ``info``):

    - ``reward_fetch = fetch_weight * fetch_rate`` (share of pieces lifted and held; by mass
      with ``fetch_by_mass=True``); 0 when the simulation diverged.
    - ``reward_deformation = -deformation_weight * D``, with each piece's excess strain
      ``e_i = min(1, max(0, LE_i - safe_log_strain))`` (LE_i its largest logarithmic strain
      during the clamp, hold and lift; the study calls LE < 0.34 no large deformation;
      ``e_i = 1`` when it passed through a blade or the plate, ``info["passed_through"]``).
      ``damage="worst"``: ``D = max_i e_i`` (one crushed piece costs the whole scene);
      ``damage="per_piece"``: ``D = sum_i s_i e_i``, ``s_i`` the piece's share of the scene
      (by count, or by mass with ``fetch_by_mass=True``), so damage is charged per piece as
      fetches are counted (``fetch_env.rewards``). This id: ``damage="{damage}"``.
    - ``reward_time = -time_weight * (theta_d / omega + hold + lift_height / lift_speed)`` [s]:
      the time a person waits for the bite. This id: ``time_weight={time_weight}``.

    ## Starting state
    At reset the scene is drawn with the env's seeded generator (``reset(seed=...)``) from the
    ranges above, or pinned with ``reset(options={{"preset": name}})`` (names:
    ``fetch_env.env_scenes.SCENE_PRESETS``: {presets}) or
    ``reset(options={{"pieces": [Piece, ...]}})``. The pieces settle on the plate with the
    half-spoons open, then the probes run (``estimator="model"`` only).

    ## Episode end
    One step is one fetch (settle, clamp to theta_d at omega, hold, lift ``lift_height`` at
    lift_speed, hold in the air): every step terminates the episode (``terminated=True``,
    never truncated). A diverged simulation ends the episode too, with ``info["error"]`` and
    no fetch reward; the next ``reset()`` works. Stepping a finished episode raises.

    ## Info
    reset: ``true_params``, ``estimated_params`` (SI, None if not identified), ``probe_piece``,
    ``probe_intervals`` (each estimate's 95 % interval ``[low, high]`` in SI, including the
    probe's model error where its calibration has an error model; None where not
    identified or a bound is not finite; the oracle's are its exact values; extrapolated
    for a piece outside the calibration's reference foods), ``probe_reliable`` (every
    parameter identified and the probes' ``reliable`` flag,
    ``fetch_env.probes.ProbeOutcome.reliable``: the intervals of g1, tau1 and mu are narrow
    and the piece lies within the calibration's reference foods, so False for, e.g., a die
    far stiffer than the food space, whose ``visco_valid`` may still be 1; without a
    calibration (``probe_calibrated=False``) there is no range to check.  The environments'
    probes give wide intervals, so the flag is rarely True: it says which estimates not to
    trust; ``docs/estimator_validation.md`` counts it per layout),
    ``probe_warnings``, ``probe_calibration`` (the calibration applied to the estimates, or
    None), ``pieces`` (scene description), ``hold``, ``clipped`` (every value clipped, capped
    or replaced: a list of ``{{"rule", "name", "given", "applied", "reason"}}``, empty when
    none; each rule also warns once per env as ``fetch_env.ParameterClippedWarning``;
    ``docs/clipping.md``).
    step: also ``reward_fetch``, ``reward_deformation``, ``reward_time``, ``fetch_rate``,
    ``fetch_rate_mass``, ``max_log_strain``, ``is_success`` (every piece fetched and
    LE_max <= safe_log_strain), ``passed_through`` (a piece passed through a blade or the
    plate), ``pieces`` (per-piece outcome), ``action_applied`` (SI),
    ``episode_time`` [s], ``traces`` (read-only mapping of 100 Hz arrays: t, phase, theta,
    theta_cmd, moment_left/right, normal_left/right, tangential_left/right, force (n, 3),
    lift, max_log_strain) and ``error`` when the physics diverged.

    For per-scene search agents: ``env.unwrapped.pieces`` (the scene's tuple of ``Piece``) and
    ``env.unwrapped.simulate_action(action) -> (reward, info)``, which runs a fetch on the
    current scene without changing the env's state (same numbers as ``step``).

    ## Arguments
    | argument | default | meaning |
    |---|---|---|
    | layout | "{layout}" | scene family: {layouts} |
    | estimator | "model" | "model", "oracle" or "none" (see Observation space) |
    | fetch_weight | 1.0 | weight of the fetch rate |
    | deformation_weight | 5.0 | penalty per unit of LE above safe_log_strain |
    | safe_log_strain | 0.34 | LE below which there is no penalty |
    | time_weight | {time_weight} | cost per second of clamp, hold and lift |
    | damage | "{damage}" | "worst" (worst piece) or "per_piece" (share-weighted sum) |
    | scenes | "{scenes}" | scene space drawn at reset (``fetch_env.env_scenes.SCENE_SPACES``) |
    | fetch_by_mass | False | reward the fetched mass share instead of the count share |
    | hold | 0.5 | hold at theta_d before lifting [s] |
    | lift_at_settling | False | hold until the estimated moment settling time t_s instead |
    | settling_tolerance | 0.1 | t_s: relaxing part of M within this share of M_inf |
    | max_hold | 5.0 | cap on the settling hold [s] |
    | lift_height | 0.005 | lift distance [m] |
    | air_hold | 0.5 | hold in the air before counting fetched pieces [s] |
    | settle | 0.2 | settling on the plate before the clamp [s] |
    | probes | "{probes}" | reset probes: "env", "measure", "repeated", "precise" |
    | probe_hold | None | relaxation probe hold [s] (None: the preset's); of the order of tau1 |
    | probe_omega | None | relaxation probe's clamping angular velocity [rad/s] (preset: 0.1) |
    | probe_strain | None | relaxation probe's squeeze past first contact, share of width (0.06) |
    | probe_time_scale | None | relaxation hold's quasi-static time scale, 1-50 (preset: 8) |
    | probe_time_growth | None | least share of the hold's elapsed time a scaled step is (0.05) |
    | probe_calibrated | True | correct the probes' systematic errors (a preset's own settings) |
    | true_stiffness | "nominal" | true K1, K2, B (info, oracle): "nominal" or "elastic_twin" |
    | contact_timeconst | 0.01 | contacts' time constant [s] (see Geometry.contact_timeconst) |
    | fetch_timestep | 0.005 | the fetch's physics step [s], 0.001-0.01 (probes keep their own) |
    | fetch_impratio | None | fetch's friction impratio, 1-1e4 (None: 1000, 100 if several pieces) |
    | fetch_hold_scale | 1.0 | fetch's holds past their first 0.1 s quasi-static, 1-20 (1: off) |
    | fetch_clamp_speed | 0.0 | slower clamps simulated at this speed [rad/s], 0.05-0.4 (0: off) |
    | render_mode | None | None, "rgb_array", "rgb_array_list" or "human" (needs a display) |
    | width | 480 | frame width [px] |
    | height | 360 | frame height [px] |
    | camera | "side" | camera name in the base scene ("side" or "front") |

    ``render_mode="rgb_array"`` gives the latest frame; ``"rgb_array_list"`` every frame
    since the last ``render()`` call at ``metadata["render_fps"]``, i.e. the whole clamp and
    lift (use it with ``gymnasium.wrappers.RecordVideo`` to see the fetch); blades and stage
    are exact, pieces are moved rigidly toward where the run left them (``fetch_env.render``).

    ``fetch_timestep`` trades fidelity for speed in multi-piece scenes, and not reliably: at
    0.01 a 9-piece diced fetch at 0.085 rad ran 3.4x real time against 1.3x (median of 5
    mixes), but the Diced env with random actions gained 0.71 -> 0.93 episodes/s over 24
    episodes (and lost, 0.98 -> 0.76, over 8); on 40 diced mixes 86 % of the pieces ended
    fetched or not as at a 2.5 ms step, against 92 % at the default 5 ms and a 93 % chaos
    floor (the 2.5 ms run against itself with every piece moved 1 nm), and 2-3x as many mixes
    crushed a soft die (``benchmarks/bench_step_size.py --twins``,
    ``docs/validation/step-size.md``).

    ``fetch_hold_scale`` > 1 steps the fetch's two holds (on the plate after the clamp, in
    the air after the lift) quasi-statically past their first 0.1 s
    (``fetch_env.controller.FETCH_HOLD_REALTIME``),
    as the relaxation probe's hold is (``fetch_env.controller.TimeScale``): each physics step
    stands for ``fetch_hold_scale`` steps of the food's relaxation, so a hold costs fewer
    steps while the blades stand still; ``info["traces"]`` then has a sample at every step of
    a scaled hold (every 25 ms at 5) instead of 100 Hz.  It changes a fetch's numbers (as a
    1 nm move of the pieces does: the fetch is chaotic), so it is off (1) on every id; how
    far outcomes move against the real-time fetch and the chaos floor, and the speed it
    buys, are measured in ``docs/validation/quasi-static-holds.md``
    (``benchmarks/bench_quasi_static.py``).

    ``fetch_clamp_speed`` > 0 simulates a clamp slower than it at that speed, each physics
    step standing for ``fetch_clamp_speed / omega`` steps of the food's relaxation
    (``fetch_env.controller.TimeScale.clamp_speed``): a slow clamp is quasi-static, so the
    blades may move as fast per step as in a real clamp at that speed while the food relaxes
    through the clamp's whole physical time.  A clamp at 0.01 rad/s then costs a tenth of
    its steps at 0.1.  Off (0) on every id, for the same reason as ``fetch_hold_scale``.
    On the same page: with ``fetch_hold_scale=5`` and ``fetch_clamp_speed=0.1`` (the clamp
    speed chosen on tuning scenes) every id's outcomes stay at the chaos floor, for 1.4-1.8x
    the episodes per core; ``fetch_env.quasi_static.quasi_static_kwargs(id)`` gives each
    id's own setting (0.2 rad/s on Block-v1, Row-v1 and Row-v2: 1.55x, 1.95x and 1.81x),
    chosen and checked the same way.  For training and large evaluations, pass it
    (``gym.make(id, **quasi_static_kwargs(id))``, ``food-fetch evaluate --quasi-static``).

    ## Version history
    - v3 (0.2.0, TwoRows): two-row plates of any shape (cube, ellipsoid, sphere) and of
      8-20 mm (``scenes="any_shape_two_rows"``), so that the clamp angle must follow the
      plate: every TwoRows-v2 plate of 8-12 mm cubes was held by a light touch, and 0.05 rad
      was within 0.05 of the best angle on all 40 tuning plates.  A 20 mm sphere needs
      0.09 rad, which crushes the smallest 0.06 MPa plates; on v3's 40 tuning plates the
      best constant angle (0.09 rad) is within 0.05 of the best on 39 and scores 0.885
      against the per-scene best's 0.898 (``benchmarks/theta_sweep.py``), a small room
      for a policy that reads the plate.  The observations
      come from the ``measure`` probes (``probes="measure"``).  Physics, actions,
      observation names, stiffness levels and rewards are those of v2.
    - v2 (0.2.0, Row): rows of any shape (cube, ellipsoid, sphere) and of 8-22 mm
      (``scenes="any_shape"``), so that the clamp angle must follow the row: every row of
      v1's 8-14 mm cubes was held and spared by the lightest touch, one constant action.
      The observations come from the ``measure`` probes (``probes="measure"``: a 20 s hold,
      mu read per half-spoon; on 32 held-back rows of the id, median / 95th-percentile
      errors g1 1.4 / 7.2 %, tau1 3.0 / 29.3 %, mu 0.4 / 7.6 % against the ``env``
      probes' 2.2 / 29.0, 5.2 / 50.0 and 1.2 / 8.8 %, for 1.36x the reset's CPU time;
      ``benchmarks/bench_env_estimates.py --scenes any_shape``).  Physics, actions,
      observation names and rewards are those of v1.
    - v2 (0.2.0, TwoRows): the v1 rewards on the "resolved" scene space
      (``scenes="resolved"``): a two-row plate's softest level is 0.06 MPa instead of
      0.0123 MPa, whose packed cubes the simulator does not resolve (their outcome changes
      with the step and impratio, so a fifth of v1's scenes were a lottery no agent
      controls).  Physics, probes, actions, observations and rewards are those of v1.
    - v1 (0.2.0): rewards and scenes that measure what a feeding robot must do, so that no
      fixed action is near the best on every scene: a time cost (``time_weight=0.1`` per
      second: a person waits for the bite), damage charged per piece by its share of the
      scene (``damage="per_piece"``: one crushed die no longer costs a whole plate), and the
      wide scene space (``scenes="wide"``: the estimators' food space, 8-25 mm, 0.0123-5 MPa,
      mu 0.1-0.8; slippery, very soft, stiff, small and large pieces).  Physics, probes,
      actions and observations are those of v0.
    - v0 (0.2.0): ``info["probe_intervals"]`` and ``info["probe_reliable"]`` say how sure
      the estimates are (a piece outside the probes' calibration, such as a die stiffer
      than the food space, is not reliable); observations unchanged.
    - v0 (0.2.0): ``true_stiffness="elastic_twin"`` defines K1, K2, B of
      ``info["true_params"]`` and the oracle as the estimators' validation does (the
      default, "nominal", is as before).
    - v0 (0.2.0): ``probes="measure"`` on Block scenes of the study space applies the
      calibration fitted on such scenes (``info["probe_calibration"]`` names it); the
      default probes' observations are unchanged.
    - v0 (0.2.0): the model's estimates are calibrated (``probe_calibrated``; False gives the
      0.1.0 estimates but for mu, now the slip ratio's 0.99 quantile where its plateau is
      lower, was 0.95); ``info["probe_calibration"]``.
    - v0 (0.1.0): first release (one fetch per episode, reset probes, model/oracle/none
      estimator): the relaxation probe's contact stiffened with the food, g1 and tau1 from
      the hold, a 6 s time-scaled relaxation hold with log-spaced steps at impratio 30
      (``probe_hold=3, probe_time_scale=1, probe_time_growth=0`` gives a 3 s real-time hold),
      a 0.15 s slide at a 10 ms step; the ``fetch_timestep`` kwarg; a piece that passed
      through a blade or the plate (``info["passed_through"]``) is never counted fetched
      and takes the whole deformation penalty; multi-piece scenes (Row, TwoRows, Diced)
      fetch at friction impratio 100 (``fetch_env.scene.MULTI_PIECE_IMPRATIO``; 1.3x faster
      over 40 diced mixes with outcomes at the chaos floor; ``fetch_impratio=1000`` gives
      1000).
"""


def _interval_or_none(bounds: tuple[float, float] | None) -> list[float] | None:
    """A 95 % interval as info holds it: ``[low, high]`` in SI, or None where the probes
    gave none or a bound is not finite."""
    if bounds is None or not all(math.isfinite(b) for b in bounds):
        return None
    return [float(bounds[0]), float(bounds[1])]


def _obs_table() -> str:
    return "\n".join(
        f"    | {i} | {n} | {OBS_TRANSFORM[n]} | {OBS_SCALE[n]:g} | {OBS_UNITS[n]} |"
        for i, n in enumerate(OBS_NAMES))


def _id_defaults(version: str, overrides: dict[str, str]) -> dict[str, Any]:
    """A registered id's defaults: its version's (``VERSION_DEFAULTS``), the "env" probes,
    and the id's own ``overrides`` over both."""
    return {**VERSION_DEFAULTS[version], "probes": "env", **overrides}


def _docstring(title: str, description: str, layout: str, version: str = "v0",
               **overrides: str) -> str:
    """An id's docstring: its description and scene ranges, then the common reference with
    the version's defaults (``VERSION_DEFAULTS``, with the id's ``overrides``) and its
    version history."""
    defaults = _id_defaults(version, overrides)
    sampling = _SPACE_SAMPLING[defaults["scenes"]]
    ranges = "\n".join(f"    - {k}: {v}" for k, v in sampling[layout].items())
    body = _COMMON_DOC.format(
        **ACTION_RANGES, bound=OBS_BOUND, n_obs=len(OBS_NAMES), obs_table=_obs_table(),
        presets=", ".join(SCENE_PRESETS), layout=layout, layouts=", ".join(LAYOUTS),
        **defaults)
    space = f'``scenes="{defaults["scenes"]}"``'
    return (f"{title}\n\n    ## Description\n    {description}\n\n"
            f"    Scene sampled at reset (``fetch_env.env_scenes``, {space}):\n{ranges}\n{body}")


def _check_reward_options(fetch_weight: float, deformation_weight: float, time_weight: float,
                          safe_log_strain: float, settling_tolerance: float,
                          max_hold: float) -> None:
    """Refuse negative or non-finite reward weights and out-of-range strain and hold settings."""
    for name, value in (("fetch_weight", fetch_weight),
                        ("deformation_weight", deformation_weight),
                        ("time_weight", time_weight)):
        require(math.isfinite(value) and value >= 0, name, value, "finite and >= 0")
    require(math.isfinite(safe_log_strain) and 0 <= safe_log_strain <= 2,
            "safe_log_strain", safe_log_strain, "in [0, 2]")
    require(0 < settling_tolerance < 1, "settling_tolerance", settling_tolerance,
            "in (0, 1)")
    require(0 <= max_hold <= 60, "max_hold", max_hold, "in [0, 60] s")


def _check_render_options(render_modes: list[str], render_mode: str | None, width: int,
                          height: int, camera: str) -> None:
    """Refuse an unknown render mode or camera, frame sizes outside [16, 4096] px, and
    ``"human"`` without a display (MuJoCo's viewer would end the process, uncatchable)."""
    require(render_mode is None or render_mode in render_modes,
            "render_mode", render_mode, f"None or one of {render_modes}")
    if render_mode == "human" and sys.platform.startswith("linux") and not (
            os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
        raise InvalidParameterError(
            "render_mode='human' needs a display (neither DISPLAY nor WAYLAND_DISPLAY is set): "
            "render off-screen with render_mode='rgb_array' or 'rgb_array_list' (MuJoCo then "
            "uses EGL, or set MUJOCO_GL=egl / osmesa), e.g. with gymnasium.wrappers.RecordVideo")
    require(isinstance(width, int) and 16 <= width <= 4096, "width", width,
            "an int in [16, 4096]")
    require(isinstance(height, int) and 16 <= height <= 4096, "height", height,
            "an int in [16, 4096]")
    require(camera in ("side", "front"), "camera", camera, "'side' or 'front'")


def _probe_config(probes: str, probe_hold: float | None, probe_omega: float | None,
                  probe_strain: float | None, probe_time_scale: float | None,
                  probe_time_growth: float | None) -> ProbeConfig:
    """The reset probes' settings: the ``probes`` preset with each ``probe_*`` given in
    place of the preset's; refuses a preset or a setting outside what the env documents."""
    require(probes in PROBE_PRESETS, "probes", probes, f"one of {tuple(PROBE_PRESETS)}")
    preset = PROBE_PRESETS[probes]
    given = {"hold": probe_hold, "omega": probe_omega, "strain": probe_strain,
             "hold_time_scale": probe_time_scale, "hold_time_growth": probe_time_growth}
    chosen = {k: getattr(preset, k) if v is None else float(v) for k, v in given.items()}
    _check_probe_options(chosen["hold"], chosen["omega"], chosen["strain"],
                         chosen["hold_time_scale"], chosen["hold_time_growth"])
    return dataclasses.replace(preset, **chosen)


def _check_probe_options(probe_hold: float, probe_omega: float, probe_strain: float,
                         probe_time_scale: float, probe_time_growth: float) -> None:
    """Refuse reset-probe settings outside the ranges the env documents."""
    require(0.05 <= probe_hold <= 60, "probe_hold", probe_hold, "in [0.05, 60] s")
    require(0.01 <= probe_omega <= 2, "probe_omega", probe_omega, "in [0.01, 2] rad/s")
    require(0 < probe_strain <= 0.3, "probe_strain", probe_strain, "in (0, 0.3]")
    require(1 <= probe_time_scale <= 50, "probe_time_scale", probe_time_scale, "in [1, 50]")
    require(0 <= probe_time_growth <= 0.5, "probe_time_growth", probe_time_growth,
            "in [0, 0.5]")


def _check_fetch_physics(fetch_timestep: float, fetch_impratio: float | None,
                         fetch_hold_scale: float, fetch_clamp_speed: float) -> None:
    """Refuse a fetch step outside [1, 10] ms, an impratio that is not None or in [1, 1e4],
    a hold scale outside [1, 20] and a clamp speed that is not 0 or in [0.05, 0.4] rad/s."""
    require(math.isfinite(fetch_hold_scale) and 1 <= fetch_hold_scale <= 20,
            "fetch_hold_scale", fetch_hold_scale, "in [1, 20]")
    require(fetch_clamp_speed == 0 or 0.05 <= fetch_clamp_speed <= 0.4,
            "fetch_clamp_speed", fetch_clamp_speed, "0 or in [0.05, 0.4] rad/s")
    require(math.isfinite(fetch_timestep) and 0.001 <= fetch_timestep <= 0.01,
            "fetch_timestep", fetch_timestep, "in [0.001, 0.01] s")
    require(fetch_impratio is None or (isinstance(fetch_impratio, (int, float))
                                       and not isinstance(fetch_impratio, bool)
                                       and math.isfinite(fetch_impratio)
                                       and 1 <= fetch_impratio <= 1e4),
            "fetch_impratio", fetch_impratio, "None or in [1, 1e4]")


class FoodFetchEnv(gym.Env[np.ndarray, np.ndarray]):
    __doc__ = _docstring(
        "Fetch soft food with a two-half-spoon end-effector (any layout).",
        "A contextual bandit: the robot sees probe-estimated food properties and the layout, "
        "picks a clamp angle, clamping speed and lift speed, and is rewarded for the pieces it "
        "lifts minus a penalty for squashing them. Reproduces the fetch of the study "
        "(README.md) on MuJoCo (fetch_env.controller).", "block")

    metadata: ClassVar[dict[str, Any]] = {
        "render_modes": ["human", "rgb_array", "rgb_array_list"], "render_fps": 25}

    def __init__(
        self,
        layout: str = "block",
        estimator: str = "model",
        fetch_weight: float = 1.0,
        deformation_weight: float = 5.0,
        safe_log_strain: float = 0.34,
        time_weight: float = 0.0,
        damage: str = "worst",
        scenes: str = "study",
        fetch_by_mass: bool = False,
        hold: float = 0.5,
        lift_at_settling: bool = False,
        settling_tolerance: float = 0.1,
        max_hold: float = 5.0,
        lift_height: float = 0.005,
        air_hold: float = 0.5,
        settle: float = 0.2,
        probes: str = "env",
        probe_hold: float | None = None,
        probe_omega: float | None = None,
        probe_strain: float | None = None,
        probe_time_scale: float | None = None,
        probe_time_growth: float | None = None,
        probe_calibrated: bool = True,
        true_stiffness: str = "nominal",
        contact_timeconst: float = 0.01,
        fetch_timestep: float = 0.005,
        fetch_impratio: float | None = None,
        fetch_hold_scale: float = 1.0,
        fetch_clamp_speed: float = 0.0,
        render_mode: str | None = None,
        width: int = 480,
        height: int = 360,
        camera: str = "side",
    ) -> None:
        check_annotated(FoodFetchEnv.__init__, locals())  # types first: ranges compare numbers
        require(layout in LAYOUTS, "layout", layout, f"one of {LAYOUTS}")
        require(estimator in ESTIMATORS, "estimator", estimator, f"one of {ESTIMATORS}")
        require(damage in DAMAGE_MODES, "damage", damage, f"one of {DAMAGE_MODES}")
        require(scenes in SCENE_SPACES, "scenes", scenes, f"one of {SCENE_SPACES}")
        require(true_stiffness in TRUE_STIFFNESS, "true_stiffness", true_stiffness,
                f"one of {TRUE_STIFFNESS}")
        _check_reward_options(fetch_weight, deformation_weight, time_weight, safe_log_strain,
                              settling_tolerance, max_hold)
        _check_render_options(self.metadata["render_modes"], render_mode, width, height, camera)
        # FetchAction and ProbeConfig validate the times and distances before any physics.
        FetchAction(hold=hold, lift_height=lift_height, air_hold=air_hold, settle=settle)
        probe_config = _probe_config(probes, probe_hold, probe_omega, probe_strain,
                                     probe_time_scale, probe_time_growth)
        _check_fetch_physics(fetch_timestep, fetch_impratio, fetch_hold_scale,
                             fetch_clamp_speed)

        self.layout = layout
        self.estimator = estimator
        self.fetch_weight = float(fetch_weight)
        self.deformation_weight = float(deformation_weight)
        self.safe_log_strain = float(safe_log_strain)
        self.time_weight = float(time_weight)
        self.damage = damage
        self.scenes = scenes
        self.fetch_by_mass = bool(fetch_by_mass)
        self.hold = float(hold)
        self.lift_at_settling = bool(lift_at_settling)
        self.settling_tolerance = float(settling_tolerance)
        self.max_hold = float(max_hold)
        self.lift_height = float(lift_height)
        self.air_hold = float(air_hold)
        self.settle = float(settle)
        self.probes = probes
        self.probe_config = probe_config
        self.geometry = Geometry(contact_timeconst=contact_timeconst)  # validates it
        self.probe_calibration = self._calibration_for(probe_calibrated)
        self.true_stiffness = true_stiffness
        self.fetch_timestep = float(fetch_timestep)
        self.fetch_impratio = None if fetch_impratio is None else float(fetch_impratio)
        self.fetch_hold_scale = float(fetch_hold_scale)
        self.fetch_clamp_speed = float(fetch_clamp_speed)
        self._fetch_time_scale = fetch_hold_time_scale(self.fetch_hold_scale,
                                                       self.fetch_clamp_speed)
        self.render_mode = render_mode
        self.width, self.height, self.camera = width, height, camera
        self._init_spaces_and_state()

    def _calibration_for(self, probe_calibrated: bool) -> Calibration | None:
        """The shipped probe calibration where asked for and fitted for these probes, else None.

        Each preset's calibration was fitted for its own settings; a preset with any setting
        changed runs uncalibrated (``info["probe_calibration"]`` says which).  Where the
        preset has one fitted on this layout's pieces in this scene space, that one
        (:func:`fetch_env.probes.calibration_for`).
        """
        require(isinstance(probe_calibrated, bool), "probe_calibrated", probe_calibrated,
                "True or False")
        preset_probes = (self.probe_config == PROBE_PRESETS[self.probes]
                         and self.geometry == Geometry())
        return (calibration_for(self.probes, self.layout, self.scenes)
                if probe_calibrated and preset_probes else None)

    def _init_spaces_and_state(self) -> None:
        """Gymnasium's spaces and the episode's state before the first reset."""
        self.action_space = spaces.Box(-1.0, 1.0, (3,), np.float32)
        self.observation_space = spaces.Box(-OBS_BOUND, OBS_BOUND, (len(OBS_NAMES),), np.float32)
        self._init_runtime()
        self.pieces: tuple[Piece, ...] = ()
        self._done = True
        self._episode_hold = self.hold
        self._last_obs: tuple[np.ndarray, dict[str, Any]] = (
            np.zeros(len(OBS_NAMES), np.float32), {})
        self.last_probe_wall_time = 0.0  # [s] probes of the latest reset (not in info: timing
        self.last_step_wall_time = 0.0  # would break same-seed determinism of infos)

    # ---------------------------------------------------------------- state not pickled
    def _init_runtime(self) -> None:
        self._sims: _LRU = _LRU()
        self._probes: _LRU = _LRU()
        self._truths: _LRU = _LRU()
        self._renderer: EpisodeRenderer | None = None
        self._frames: list[np.ndarray] = []
        self._last_result: SimResult | None = None
        self._viewer: Any = None

    def __getstate__(self) -> dict[str, Any]:
        state = self.__dict__.copy()
        for key in ("_sims", "_probes", "_truths", "_renderer", "_frames", "_last_result",
                    "_viewer"):
            state.pop(key, None)
        return state

    def __setstate__(self, state: dict[str, Any]) -> None:
        self.__dict__.update(state)
        self._init_runtime()

    # ---------------------------------------------------------------- gymnasium API
    def reset(self, *, seed: int | None = None,
              options: dict[str, Any] | None = None) -> tuple[np.ndarray, dict[str, Any]]:
        seed, options = check_reset(seed, options)
        super().reset(seed=seed)
        unknown = sorted(set(options) - set(RESET_OPTIONS))
        if unknown:
            raise InvalidParameterError(
                f"unknown reset option(s) {unknown}; valid options: {RESET_OPTIONS}")
        if "preset" in options and "pieces" in options:
            raise InvalidParameterError("reset options 'preset' and 'pieces' exclude each other")
        if "pieces" in options:
            pieces = tuple(options["pieces"])
            require(len(pieces) >= 1, "options['pieces']", options["pieces"], "non-empty")
            for i, p in enumerate(pieces):
                require(isinstance(p, Piece), f"options['pieces'][{i}]", p, "a Piece")
        elif "preset" in options:
            pieces = preset_scene(options["preset"])
        else:
            pieces = sample_scene(self.layout, self.np_random, self.scenes)
        with clipping.reported_elsewhere():  # in info["clipped"], warned once per env
            self._sim_for(pieces).scene_for("fetch")  # compile now: bad pieces fail at reset
            self.pieces = pieces
            obs, info = self._observe(pieces)
        info["clipped"] = self._last_obs[1]["clipped"] = clipping.reset_clips(self, pieces, info)
        clipping.warn_once(self, info["clipped"], 'info["clipped"]')
        self._done = False
        self._last_result = None
        if self.render_mode is not None:
            self._frames = [self._get_renderer().rest_frame(self._sim_for(pieces)
                                                            .scene_for("fetch"))]
            if self.render_mode == "human":
                self.render()
        return obs, info

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        if self._done:
            raise RuntimeError("the episode has ended (one fetch per episode): call reset()")
        wall = time.perf_counter()
        reward, info, result = self._simulate(action)
        self.last_step_wall_time = time.perf_counter() - wall
        self._done = True
        self._last_result = result
        if self.render_mode is not None and result is not None:
            scene = self._sim_for(self.pieces).scene_for("fetch")
            self._frames = self._get_renderer().replay(
                scene, result.traces, result.pieces, self.metadata["render_fps"])
            if self.render_mode == "human":
                self.render()
        obs, _ = self._last_obs
        return obs.copy(), reward, True, False, info

    def render(self) -> np.ndarray | list[np.ndarray] | None:
        if self.render_mode is None:
            gym.logger.warn("render() called without a render_mode; pass render_mode=...")
            return None
        if not self._frames:
            if not self.pieces:
                raise RuntimeError("call reset() before render()")
            self._frames = [self._get_renderer().rest_frame(
                self._sim_for(self.pieces).scene_for("fetch"))]
        if self.render_mode == "rgb_array":
            return self._frames[-1]
        if self.render_mode == "rgb_array_list":
            frames, self._frames = self._frames, self._frames[-1:]
            return frames
        self._show_human()
        return None

    def close(self) -> None:
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None
        if self._viewer is not None:
            self._viewer.close()
            self._viewer = None
        self._sims.clear()
        self._probes.clear()

    # ---------------------------------------------------------------- for search agents
    def simulate_action(self, action: np.ndarray) -> tuple[float, dict[str, Any]]:
        """Run a fetch with ``action`` on the current scene; the env's state is unchanged.

        Returns ``(reward, info)`` exactly as :meth:`step` would (the physics is
        deterministic), so a per-scene search can evaluate many actions on one scene.
        """
        if not self.pieces:
            raise RuntimeError("call reset() before simulate_action()")
        reward, info, _ = self._simulate(action)
        return reward, info

    # ---------------------------------------------------------------- internals
    def _sim_for(self, pieces: tuple[Piece, ...]) -> FetchSimulator:
        return self._sims.get_or(pieces, lambda: FetchSimulator(pieces, self.geometry,
                                                                timestep=self.fetch_timestep,
                                                                impratio=self.fetch_impratio))

    def _get_renderer(self) -> EpisodeRenderer:
        if self._renderer is None:
            self._renderer = EpisodeRenderer(self.width, self.height, self.camera)
        return self._renderer

    def _observe(self, pieces: tuple[Piece, ...]) -> tuple[np.ndarray, dict[str, Any]]:
        k = probe_piece_index(pieces)
        warnings: list[str] = []
        true = self._true_params(pieces[k], warnings)
        wall = time.perf_counter()
        if self.estimator == "model":
            # Probes depend only on the probed piece (simulated alone) and the config.
            outcome: ProbeOutcome = self._probes.get_or(
                (pieces[k], self.probe_config, self.probe_calibration is not None),
                lambda: run_probes(pieces, self.probe_config, self.geometry,
                                   calibration=self.probe_calibration))
            est = dict(outcome.estimates)
            flags = {"visco_valid": float(outcome.visco_valid),
                     "friction_valid": float(outcome.friction_valid)}
            warnings = list(outcome.warnings)
            reliable, intervals = outcome.reliable, dict(outcome.intervals)
        elif self.estimator == "oracle":
            est = dict(true)
            flags = {"visco_valid": 1.0, "friction_valid": 1.0}
            reliable, intervals = True, {n: (v, v) for n, v in true.items()}
        else:
            est = dict.fromkeys(PARAM_NAMES, math.nan)
            flags = {"visco_valid": 0.0, "friction_valid": 0.0}
            reliable, intervals = False, {}
        self.last_probe_wall_time = time.perf_counter() - wall
        obs = encode_observation({**est, **flags, **layout_features(pieces)})
        # What the policy actually sees: a parameter dropped by the encoder is NaN here too.
        seen = decode_observation(obs)
        # None, not NaN, where not identified: NaN != NaN would make equal infos compare
        # unequal (gymnasium's determinism checks use ==).
        estimated = {n: (float(est[n]) if math.isfinite(seen[n]) else None)
                     for n in PARAM_NAMES}
        bounds = {n: _interval_or_none(intervals.get(n)) if estimated[n] is not None else None
                  for n in PARAM_NAMES}
        self._episode_hold = self._hold_from(estimated)
        info = {"true_params": {n: (float(v) if math.isfinite(v) else None)
                                for n, v in true.items()},
                "estimated_params": estimated, "probe_piece": k,
                "probe_reliable": bool(reliable and all(v is not None
                                                        for v in estimated.values())),
                "probe_intervals": bounds,
                "probe_warnings": warnings, "pieces": [p.to_dict() for p in pieces],
                "probe_calibration": (self.probe_calibration.source
                                      if self.probe_calibration and self.estimator == "model"
                                      else None),
                "hold": self._episode_hold}
        self._last_obs = (obs, info)
        return obs.copy(), dict(info)

    def _true_params(self, piece: Piece, warnings: list[str]) -> dict[str, float]:
        """The probed piece's true parameters as ``true_stiffness`` defines K1, K2, B; where
        its elastic twin is held at no placement (its stiffness undefined), K1, K2 and B
        are NaN (None in ``info["true_params"]``) and ``warnings`` says why."""
        if self.true_stiffness == "nominal":
            return true_parameters(piece)
        try:  # the twin is placed where the probes clamp (elastic_stiffness)
            return dict(self._truths.get_or(
                (piece, self.probe_config),
                lambda: true_parameters_exact(piece, self.probe_config, self.geometry)))
        except SimulationDivergedError as exc:
            warnings.append(f"true stiffness: {exc}")
            return {**true_parameters(piece), "K1": math.nan, "K2": math.nan, "B": math.nan}

    def _hold_from(self, est: dict[str, float | None]) -> float:
        """The hold before lifting: fixed, or the settling time t_s from the estimates.

        After the clamp the moment relaxes as M_inf + A exp(-t / tau1) (eq. 6); for a fast
        clamp A / M_inf is about g1 / (1 - g1), so the relaxing part is within
        ``settling_tolerance`` of M_inf after tau1 * ln(g1 / ((1 - g1) tol)).
        """
        if not self.lift_at_settling:
            return self.hold
        g1, tau1 = est.get("g1"), est.get("tau1")
        if g1 is None or tau1 is None or not (0 < g1 < 1 and tau1 > 0):
            return self.hold
        ratio = g1 / ((1 - g1) * self.settling_tolerance)
        return float(min(max(tau1 * math.log(max(ratio, 1.0)), 0.0), self.max_hold))

    def _simulate(self, action: Any) -> tuple[float, dict[str, Any], SimResult | None]:
        action, clipped = clip_action(action)  # [-1, 1]; reported in info, warned once
        phys = action_to_physical(action)
        sim = self._sim_for(self.pieces)
        closed = getattr(sim.scene_for("fetch").pose, "theta_closed", math.inf)
        theta_d, capped = theta_d_cap(phys["theta_d"], closed)
        clipped += capped
        fa = FetchAction(theta_d=theta_d, omega=phys["omega"], lift_speed=phys["lift_speed"],
                         hold=self._episode_hold, lift_height=self.lift_height,
                         air_hold=self.air_hold, settle=self.settle)
        duration = fetch_duration(fa.theta_d, fa.omega, fa.hold, fa.lift_height, fa.lift_speed)
        reward_time = -self.time_weight * duration
        info: dict[str, Any] = dict(self._reset_info_copy())
        info["action_applied"] = {"theta_d": fa.theta_d, "omega": fa.omega,
                                  "lift_speed": fa.lift_speed, "hold": fa.hold}
        info["episode_time"] = duration
        info["clipped"] = [*info.get("clipped", []), *clipped]
        clipping.warn_once(self, clipped, 'info["clipped"]')
        try:
            result: SimResult | None = sim.run("fetch", fa, time_scale=self._fetch_time_scale)
        except SimulationDivergedError as exc:
            result = None
            info.update(reward_fetch=0.0, reward_deformation=0.0, reward_time=reward_time,
                        fetch_rate=0.0, fetch_rate_mass=0.0, max_log_strain=None,
                        is_success=False, passed_through=False, pieces=[], traces=Traces({}),
                        error=exc.one_line())
            return float(reward_time), info, None
        assert result is not None
        stop = end_stop_records(fa.theta_d, result.extra, closed)
        info["clipped"] += stop
        clipping.warn_once(self, stop, 'info["clipped"]')
        le = max(max(p["max_log_strain_clamp"], p["max_log_strain_lift"])
                 for p in result.pieces)
        share = result.fetch_rate_mass if self.fetch_by_mass else result.fetch_rate
        reward_fetch = self.fetch_weight * float(share)
        passed = any(p["passed_through"] for p in result.pieces)
        excess = damage_excess(result.pieces, self.safe_log_strain, self.damage,
                               self.fetch_by_mass)
        reward_def = -self.deformation_weight * excess
        info.update(reward_fetch=reward_fetch, reward_deformation=reward_def,
                    reward_time=reward_time, fetch_rate=float(result.fetch_rate),
                    fetch_rate_mass=float(result.fetch_rate_mass), max_log_strain=float(le),
                    is_success=bool(result.fetch_rate >= 1.0 and le <= self.safe_log_strain),
                    passed_through=passed, pieces=result.pieces, traces=Traces(result.traces))
        return float(reward_fetch + reward_def + reward_time), info, result

    def _reset_info_copy(self) -> dict[str, Any]:
        _, info = self._last_obs
        return {k: (dict(v) if isinstance(v, dict) else v) for k, v in info.items()}

    def _show_human(self) -> None:
        import mujoco.viewer  # needs a display; imported only here

        scene = self._sim_for(self.pieces).scene_for("fetch")
        frames = self._frames
        self._frames = frames[-1:]
        if self._viewer is None:
            from fetch_env.scene import initial_state

            self._viewer_data = initial_state(scene)
            self._viewer = mujoco.viewer.launch_passive(scene.model, self._viewer_data)
        # The viewer shows the live model; replay timing only (frames are for rgb modes).
        for _ in frames:
            self._viewer.sync()
            time.sleep(1.0 / self.metadata["render_fps"])


def _with_defaults(default: str, version: str = "v0", **overrides: str) -> Callable[..., None]:
    """An ``__init__`` for a registered id's class: :class:`FoodFetchEnv`'s with ``layout``
    defaulting to the id's scene family, the reward and scene arguments to its version's
    (``VERSION_DEFAULTS``) and ``probes`` to "env", each replaced by the id's ``overrides``
    (the same as given to :func:`_docstring`); every other argument passed through."""
    d = _id_defaults(version, overrides)

    def __init__(self: FoodFetchEnv, layout: str = default,
                 time_weight: float = d["time_weight"], damage: str = d["damage"],
                 scenes: str = d["scenes"], probes: str = d["probes"], **kwargs: Any) -> None:
        FoodFetchEnv.__init__(self, layout=layout, time_weight=time_weight, damage=damage,
                              scenes=scenes, probes=probes, **kwargs)

    return __init__


class FoodFetchBlockEnv(FoodFetchEnv):
    __doc__ = _docstring(
        "FoodFetch-Block-v0: fetch one soft block.",
        "One piece (cube, ellipsoid or sphere) of a sampled viscoelastic material, the "
        "study's block experiments; the fastest id (about 2.3-2.5 episodes a second on one core "
        "on the project's 2-core VM, docs/benchmarks.md).",
        "block")

    __init__ = _with_defaults("block")


class FoodFetchRowEnv(FoodFetchEnv):
    __doc__ = _docstring(
        "FoodFetch-Row-v0: fetch a single row of cubes.",
        "Two or three cubes side by side across the clamp direction, at one of the study's "
        "spacings (1, 0.5, 0.3, 0.1 mm); the study found tighter rows fetched better.", "row")

    __init__ = _with_defaults("row")


class FoodFetchTwoRowsEnv(FoodFetchEnv):
    __doc__ = _docstring(
        "FoodFetch-TwoRows-v0: fetch two rows of hard or soft cubes.",
        "Two rows of cubes, 1 mm apart along the clamp and 0.01 mm across, all 200 MPa "
        "(hard) or all 0.2 MPa (soft): the study's soft-against-hard comparison.", "two_rows")

    __init__ = _with_defaults("two_rows")


class FoodFetchDicedEnv(FoodFetchEnv):
    __doc__ = _docstring(
        "FoodFetch-Diced-v0: fetch a diced mix of shapes and stiffnesses.",
        "Four to eight small pieces (cube, ellipsoid, sphere) of the study's five stiffness "
        "levels (200, 40, 5, 0.15, 0.0123 MPa) packed on a jittered grid; hard pieces tend to "
        "escape the clamp.", "diced")

    __init__ = _with_defaults("diced")


