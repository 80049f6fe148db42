"""A saved Stable-Baselines3 model (PPO or SAC ``.zip``) as an :class:`~agents.base.Agent`.

A model file is untrusted input: SB3 keeps some of a model's attributes in the zip's ``data``
entry as cloudpickled objects, and unpickling runs whatever code the file names.  Loading here
never unpickles them: :func:`safe_custom_objects` rebuilds every such entry (the policy class,
the spaces, the schedules, the rollout state) from the environment, the numbers SB3 writes
beside each pickle and the run's config.yml, and hands them to SB3 as ``custom_objects``, which
SB3 uses instead of unpickling.  A pickled entry it cannot rebuild refuses the file.  The
network weights are read by ``torch.load(weights_only=True)``, which loads tensors only.

SB3 and torch are imported only when a model is loaded (the ``train`` extra).
"""

from __future__ import annotations

import re
import zipfile
from pathlib import Path
from typing import Any

import numpy as np

from agents.base import Agent


class ModelLoadError(Exception):
    """The file is missing or is not a loadable SB3 model (one line)."""


def model_data(path: str | Path) -> dict[str, Any]:
    """The ``data`` entry of a saved SB3 model (JSON, read without torch): its constructor
    arguments and ``num_timesteps``.  ModelLoadError when the file is not such a model."""
    import json

    try:
        with zipfile.ZipFile(path) as zf:
            data = json.loads(zf.read("data").decode())
    except OSError as exc:
        raise ModelLoadError(f"cannot read {str(path)!r}: {exc.strerror}") from None
    except zipfile.BadZipFile:
        raise ModelLoadError(f"{str(path)!r} is not a valid Stable-Baselines3 model "
                             "(not a zip file)") from None
    except (KeyError, UnicodeDecodeError, ValueError):
        raise ModelLoadError(f"{str(path)!r} is not a valid Stable-Baselines3 model "
                             "(no readable 'data' entry in the zip)") from None
    if not isinstance(data, dict):
        raise ModelLoadError(f"{str(path)!r} is not a valid Stable-Baselines3 model "
                             "(its 'data' entry is not a mapping)")
    return data


def algo_of_data(data: dict[str, Any]) -> str | None:
    """'ppo' or 'sac' from a model's ``data``: SAC's policy lives in stable_baselines3.sac,
    PPO's is the shared ActorCriticPolicy, told apart by PPO's own arguments."""
    policy = data.get("policy_class")
    module = policy.get("__module__", "") if isinstance(policy, dict) else ""
    if str(module).startswith("stable_baselines3.sac."):
        return "sac"
    if "clip_range" in data and "n_epochs" in data:
        return "ppo"
    return None


# Pickled entries of a model's data that are the rollout's state: SB3 rebuilds them when
# learning starts (``_setup_learn`` resets the env when ``_last_obs`` is None), so None is
# exactly what a loaded model needs.
ROLLOUT_STATE: tuple[str, ...] = ("_last_obs", "_last_episode_starts", "_last_original_obs",
                                  "ep_info_buffer", "ep_success_buffer")
# Pickled entries rebuilt from a number: SB3's ``_setup_model`` turns a float into its
# schedule (learning_rate, clip_range) and an int or [n, unit] into SAC's TrainFreq.
NUMBERS: dict[str, float | int | None] = {"learning_rate": 3e-4, "clip_range": 0.2,
                                          "clip_range_vf": None, "train_freq": 1}
# Classes that ``_setup_model`` picks itself when given None (the default buffers), and the
# learning-rate schedule, which it rebuilds from learning_rate.
REBUILT_BY_SB3: tuple[str, ...] = ("rollout_buffer_class", "replay_buffer_class",
                                   "lr_schedule")
_CONSTANT = re.compile(r"^ConstantSchedule\(val=([-+0-9.eE]+|inf)\)$")
_SPACE_DTYPES = ("float32", "float64")


def _pickled(value: Any) -> bool:
    return isinstance(value, dict) and ":serialized:" in value


def _constant_hint(entry: dict[str, Any]) -> float | None:
    """The value of a constant schedule from the text SB3 writes beside its pickle
    ("ConstantSchedule(val=0.2)"); None for any other schedule."""
    m = _CONSTANT.match(str(entry.get("value_schedule", "")))
    return float(m.group(1)) if m else None


def box_from_hint(entry: Any) -> Any:
    """A gymnasium ``Box`` rebuilt from the text SB3 writes beside a pickled Box (dtype,
    shape, low, high), or None when the entry is not such a Box or its numbers are
    abbreviated.  Only numbers are read; nothing is unpickled."""
    from gymnasium.spaces import Box

    if not isinstance(entry, dict) or "gymnasium.spaces.box.Box" not in str(entry.get(":type:")):
        return None
    shape, dtype = entry.get("_shape"), entry.get("dtype")
    if (not isinstance(shape, list) or not all(isinstance(n, int) and n > 0 for n in shape)
            or dtype not in _SPACE_DTYPES):
        return None
    bounds = []
    for key in ("low", "high"):
        text = str(entry.get(key, "")).replace("[", " ").replace("]", " ")
        try:
            values = np.array([float(tok) for tok in text.split()], dtype=dtype)
        except ValueError:  # "..." in a long array's text, or anything else
            return None
        if values.size != int(np.prod(shape)):
            return None
        bounds.append(values.reshape(shape))
    return Box(low=bounds[0], high=bounds[1], shape=tuple(shape), dtype=dtype)


def config_near(path: Path) -> dict[str, Any]:
    """The hyperparameters in the config.yml of the run a model file belongs to (beside it,
    or one folder up for checkpoints/ and eval/), read with ``yaml.safe_load``; {} if none."""
    import yaml

    for cfg in (path.parent / "config.yml", path.parent.parent / "config.yml"):
        if not cfg.is_file():
            continue
        try:
            hp = (yaml.safe_load(cfg.read_text()) or {}).get("hyperparams")
        except (OSError, UnicodeDecodeError, yaml.YAMLError, AttributeError):
            continue
        if isinstance(hp, dict):
            return hp
    return {}


def _space(data: dict[str, Any], key: str, given: Any, name: str) -> Any:
    hinted = box_from_hint(data.get(key))
    if given is None:
        if hinted is None:
            raise ModelLoadError(f"{name}: cannot rebuild its {key} without unpickling it; "
                                 "give the environment it was trained on")
        return hinted
    if hinted is not None and hinted.shape != given.shape:
        raise ModelLoadError(f"{name} was trained with an {key} of shape {hinted.shape}, the "
                             f"environment's is {given.shape}")
    return given


def safe_custom_objects(data: dict[str, Any], algo: str, name: str, *,
                        observation_space: Any = None, action_space: Any = None,
                        settings: dict[str, Any] | None = None,
                        for_training: bool = False) -> dict[str, Any]:
    """Replacements for every cloudpickled entry of a model's ``data``, to pass to SB3's
    ``load(custom_objects=...)`` so that nothing in the file is unpickled.

    The policy class is the algorithm's MlpPolicy; the spaces are the environment's (checked
    against the shapes the file states) or, without one, rebuilt from those numbers; constant
    schedules from the numbers SB3 writes beside them, else ``settings`` (the run's config),
    else SB3's defaults; the rollout state None.  ModelLoadError names a pickled entry that
    cannot be rebuilt (custom policy arguments, an action noise object when training)."""
    from stable_baselines3 import PPO, SAC

    cls = {"ppo": PPO, "sac": SAC}[algo]
    settings = settings or {}
    custom: dict[str, Any] = {
        "policy_class": cls.policy_aliases["MlpPolicy"],
        "observation_space": _space(data, "observation_space", observation_space, name),
        "action_space": _space(data, "action_space", action_space, name),
        **{key: None for key in REBUILT_BY_SB3 + ROLLOUT_STATE},
    }
    for key, default in NUMBERS.items():
        if key in data and _pickled(data[key]):
            hinted = _constant_hint(data[key])
            value = hinted if hinted is not None else settings.get(key, default)
            # SAC reads [n, "step" | "episode"] (config.yml's form) only as a tuple
            custom[key] = tuple(value) if isinstance(value, list) else value
    if not for_training and _pickled(data.get("action_noise")):
        custom["action_noise"] = None  # exploration noise: unused by predict()
    left = sorted(k for k, v in data.items() if _pickled(v) and k not in custom)
    if left:
        raise ModelLoadError(f"{name} holds a pickled {left[0]!r}, which food-fetch does not "
                             "unpickle (loading a pickle can run code) and cannot rebuild: "
                             "retrain the model with food-fetch train")
    return custom


def _algo_of(path: Path) -> str | None:
    """'ppo' or 'sac' from the model's own metadata or, failing that, a config.yml next to
    it (the metadata first: a config.yml can belong to a later run in the same folder)."""
    try:
        algo = algo_of_data(model_data(path))
    except ModelLoadError:
        algo = None
    if algo is not None:
        return algo
    cfg = path.parent / "config.yml"
    if cfg.is_file():
        import yaml

        try:
            algo = (yaml.safe_load(cfg.read_text()) or {}).get("algo")
        except (OSError, UnicodeDecodeError, yaml.YAMLError, AttributeError):
            algo = None
        if algo in ("ppo", "sac"):
            return str(algo)
    return None


class SB3Agent(Agent):
    """Deterministic actions of a saved PPO or SAC policy."""

    def __init__(self, path: str | Path, deterministic: bool = True) -> None:
        super().__init__()
        self.path = Path(path)
        if not self.path.is_file():
            raise ModelLoadError(f"model file not found: {str(path)!r}")
        if not zipfile.is_zipfile(self.path):
            raise ModelLoadError(f"not a Stable-Baselines3 model (.zip): {str(path)!r}")
        self.algo = _algo_of(self.path)
        if self.algo is None:
            raise ModelLoadError(f"cannot tell PPO or SAC from {str(path)!r}")
        self.name = str(path)
        self.deterministic = deterministic
        self._model: Any = None
        self._spaces: tuple[Any, Any] = (None, None)

    def begin_episode(self, env: Any) -> None:
        """Keep the environment's spaces: the model is loaded with them (see
        :func:`safe_custom_objects`)."""
        if self._model is None:
            self._spaces = (env.observation_space, env.action_space)

    @property
    def model(self) -> Any:
        if self._model is None:
            try:
                import torch
                from stable_baselines3 import PPO, SAC
            except ImportError:
                raise ModelLoadError("loading a model needs the train extra: "
                                     "pip install -e '.[train]'") from None
            torch.set_num_threads(1)
            cls = {"ppo": PPO, "sac": SAC}[self.algo]  # type: ignore[index]
            name = repr(str(self.path))
            custom = safe_custom_objects(
                model_data(self.path), str(self.algo), name, observation_space=self._spaces[0],
                action_space=self._spaces[1], settings=config_near(self.path))
            try:
                self._model = cls.load(str(self.path), device="cpu", custom_objects=custom)
            except Exception as exc:  # a corrupt or foreign zip: one line, not a traceback
                raise ModelLoadError(f"cannot load {str(self.path)!r} as {self.algo}: "
                                     f"{type(exc).__name__}: {exc}") from None
        return self._model

    def act(self, obs: np.ndarray) -> np.ndarray:
        action, _ = self.model.predict(np.asarray(obs, np.float32),
                                       deterministic=self.deterministic)
        return np.asarray(action, np.float32).reshape(3)

    def describe(self) -> dict[str, Any]:
        return {"name": self.name, "algo": self.algo, "path": str(self.path)}

    def __getstate__(self) -> dict[str, Any]:  # workers reload the model themselves
        state = self.__dict__.copy()
        state["_model"] = None
        return state
