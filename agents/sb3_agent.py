"""A saved Stable-Baselines3 model (PPO or SAC ``.zip``) as an :class:`~agents.base.Agent`.

SB3 and torch are imported only when a model is loaded (the ``train`` extra).
"""

from __future__ import annotations

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
            try:
                self._model = cls.load(str(self.path), device="cpu")
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
