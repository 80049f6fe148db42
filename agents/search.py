"""``search``: the best action for each scene found by running the simulator itself.

The per-scene optimum is what no policy that sees only the observation can beat (up to the
search's resolution), so ``reward(search) - reward(agent)`` on the same seeded scene is the
agent's regret.  The search evaluates candidates with ``env.unwrapped.simulate_action``
(the env's state is not changed; the physics is deterministic, so ``step`` with the chosen
action gives the same reward):

1. a grid of clamp angles over the whole action range at the study's clamp and lift speeds,
   plus the study's and the model-based agent's actions (so the search never loses to them);
2. a refinement of theta_d around the best angle (halving the step, ``refine`` times);
3. the best angle with a few other clamp and lift speeds.

Ties are broken by the lower peak strain (more margin).  About ``len(grid) + 2 + 2 refine +
len(speeds)`` simulations per scene (~25: ~5-10 s per Block scene on one core).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from agents.base import Agent
from fetch_env.env import ACTION_RANGES, physical_to_action

# Set in a Ray worker (agents.ray_runner): each round of independent simulations of a scene
# then runs as Ray tasks across the cluster, with the same numbers.
SPREAD_ON_RAY = False

# (omega [rad/s], lift_speed [m/s]) tried at the best angle: the study's neighbours, and the
# fast ones a time cost (the -v1 ids) rewards.
SPEEDS: tuple[tuple[float, float], ...] = ((0.05, 0.005), (0.2, 0.005), (0.1, 0.01),
                                           (0.1, 0.004), (0.4, 0.04), (0.2, 0.02), (0.4, 0.01))


class SearchAgent(Agent):
    """Per-scene search over the action with the simulator (the regret reference)."""

    name = "search"

    def __init__(self, n_grid: int = 11, refine: int = 2,
                 speeds: tuple[tuple[float, float], ...] = SPEEDS,
                 seed_actions: bool = True) -> None:
        super().__init__()
        self.n_grid, self.refine, self.speeds = n_grid, refine, speeds
        self.seed_actions = seed_actions
        self._env: Any = None
        self._scene_seed: int | None = None
        self.last_search: dict[str, Any] = {}

    def begin_episode(self, env: Any) -> None:
        self._env = env.unwrapped

    def seed(self, seed: int | None = None) -> None:
        super().seed(seed)
        self._scene_seed = seed  # the evaluation resets the scene with the agent's seed

    def _score(self, action: np.ndarray) -> tuple[float, float]:
        reward, info = self._env.simulate_action(action)
        return _score_of(float(reward), info)

    def _score_round(self, keys: list[tuple[float, float, float]],
                     tried: dict[tuple[float, float, float], tuple[float, float]]) -> None:
        """Score the keys not yet tried, in order (one round: independent simulations, on
        the Ray cluster when this episode runs there, else one after the other)."""
        new = [k for i, k in enumerate(keys) if k not in tried and k not in keys[:i]]
        if SPREAD_ON_RAY and len(new) > 1 and self._scene_seed is not None:
            scores = _scores_on_ray(self._env, self._scene_seed, new)
        else:
            scores = [self._score(physical_to_action(*k)) for k in new]
        tried.update(zip(new, scores, strict=True))

    def act(self, obs: np.ndarray) -> np.ndarray:
        if self._env is None:
            raise RuntimeError("search needs the env: call begin_episode(env) after reset")
        lo, hi = ACTION_RANGES["theta_d"]
        base_omega, base_lift = 0.1, 0.005
        tried: dict[tuple[float, float, float], tuple[float, float]] = {}

        def key(theta: float, omega: float, lift: float) -> tuple[float, float, float]:
            return (round(float(np.clip(theta, lo, hi)), 6), omega, lift)

        grid = [key(float(t), base_omega, base_lift) for t in np.linspace(lo, hi, self.n_grid)]
        self._score_round(grid + self._seed_keys(obs, key, base_omega, base_lift), tried)
        step = (hi - lo) / (self.n_grid - 1)
        for _ in range(self.refine):
            step /= 2
            best = max(tried.items(), key=lambda kv: kv[1])[0]
            self._score_round([key(t, best[1], best[2]) for t in (best[0] - step,
                               best[0] + step) if lo <= t <= hi], tried)
        best = max(tried.items(), key=lambda kv: kv[1])[0]
        self._score_round([key(best[0], omega, lift) for omega, lift in self.speeds], tried)
        best, (reward, neg_le) = max(tried.items(), key=lambda kv: kv[1])
        self.last_search = {"theta_d": best[0], "omega": best[1], "lift_speed": best[2],
                            "reward": reward, "max_log_strain": -neg_le,
                            "n_simulations": len(tried)}
        return physical_to_action(*best)

    def _seed_keys(self, obs: np.ndarray, key: Callable[..., tuple[float, float, float]],
                   base_omega: float, base_lift: float) -> list[tuple[float, float, float]]:
        """The study's and model-based's actions, each also at the study's speeds."""
        if not self.seed_actions:
            return []
        from agents.baselines import StudyAgent
        from agents.model_based import ModelBasedAgent

        keys = []
        for agent in (StudyAgent(), ModelBasedAgent()):
            agent.begin_episode(self._env)
            phys = _phys(agent.act(obs))
            keys += [key(*phys), key(phys[0], base_omega, base_lift)]
        return keys

    def describe(self) -> dict[str, Any]:
        return {"name": self.name, "n_grid": self.n_grid, "refine": self.refine,
                "speeds": [list(s) for s in self.speeds], "seed_actions": self.seed_actions}


def _phys(action: np.ndarray) -> tuple[float, float, float]:
    from fetch_env.env import action_to_physical

    p = action_to_physical(action)
    return (round(p["theta_d"], 6), round(p["omega"], 6), round(p["lift_speed"], 6))


def _score_of(reward: float, info: dict[str, Any]) -> tuple[float, float]:
    """The search's score: the reward, ties broken by the lower peak strain."""
    le = info.get("max_log_strain")
    return reward, -(float(le) if le is not None else 10.0)


def _scores_on_ray(env: Any, scene_seed: int,
                   keys: list[tuple[float, float, float]]) -> list[tuple[float, float]]:
    """Each key simulated on the scene of ``reset(seed=scene_seed)`` as a Ray task."""
    import ray

    if not _REMOTE:  # exported to the cluster once per process, not once per round
        _REMOTE.append(ray.remote(num_cpus=1, max_retries=1)(_simulate_key))
    spec = env.spec
    return ray.get([_REMOTE[0].remote(spec.id, dict(spec.kwargs), scene_seed, k)
                    for k in keys])


def _simulate_key(env_id: str, env_kwargs: dict[str, Any], scene_seed: int,
                  key: tuple[float, float, float]) -> tuple[float, float]:
    """On a Ray worker: one candidate on the scene.  The worker keeps an env of its own for
    these simulations (not the episodes' one), reset only when the scene changes."""
    import gymnasium as gym

    from agents.evaluate import warm_up

    warm_up()
    cache_key = (env_id, repr(sorted(env_kwargs.items())))
    if cache_key not in _SIM_ENVS:
        _SIM_ENVS[cache_key] = [gym.make(env_id, **env_kwargs).unwrapped, None]
    entry = _SIM_ENVS[cache_key]
    if entry[1] != scene_seed:
        entry[0].reset(seed=scene_seed)
        entry[1] = scene_seed
    reward, info = entry[0].simulate_action(physical_to_action(*key))
    return _score_of(float(reward), info)


_SIM_ENVS: dict[tuple[str, str], list[Any]] = {}
_REMOTE: list[Any] = []
