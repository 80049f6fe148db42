"""A policy trained by RLlib, as a file that evaluates without Ray, torch or pickle.

``food-fetch train --backend rllib`` ends by exporting the actor of the trained RLModule to
``policy.npz`` (its layers' weights, numpy arrays) and ``policy.json`` (the layer order,
activations, how the action is read off the network's output).  :class:`RLlibPolicyAgent`
runs that network in numpy: the deterministic action (the Gaussian's mean; for SAC's
squashed Gaussian, its tanh), clipped to the action box.  The export checks itself against
the module's own ``forward_inference`` on random observations before it writes anything.

Why not load RLlib's checkpoint to evaluate: it restores pickled Python objects (code from
the file) and needs Ray and torch on the evaluating machine; the weights alone need neither
(docs/security.md).
"""

from __future__ import annotations

import io
import json
from pathlib import Path
from typing import Any

import numpy as np

from agents.base import Agent

FORMAT = "food-fetch-rllib-policy/1"
ACTIVATIONS = {"tanh": np.tanh, "relu": lambda x: np.maximum(x, 0.0),
               "linear": lambda x: x, None: lambda x: x}
# The actor's layers in an RLlib default module: (encoder prefix, head prefix) by how PPO's
# value function shares the encoder; SAC has its own policy encoder.
_PREFIXES = {("ppo", True): ("encoder.encoder.net.mlp.", "pi.net.mlp."),
             ("ppo", False): ("encoder.actor_encoder.net.mlp.", "pi.net.mlp."),
             ("sac", True): ("pi_encoder.net.mlp.", "pi.net.mlp."),
             ("sac", False): ("pi_encoder.net.mlp.", "pi.net.mlp.")}


class PolicyFileError(Exception):
    """A policy file that cannot be read or is not a food-fetch RLlib policy (one line)."""


def _layers(state: dict[str, Any], prefix: str) -> list[tuple[np.ndarray, np.ndarray]]:
    """The (weight, bias) of each Linear layer under ``prefix``, in order."""
    idx = sorted({int(k[len(prefix):].split(".")[0]) for k in state
                  if k.startswith(prefix) and k.endswith(".weight")})
    return [(np.asarray(state[f"{prefix}{i}.weight"], np.float64),
             np.asarray(state[f"{prefix}{i}.bias"], np.float64)) for i in idx]


def export_policy(module: Any, algo: str, env_id: str, out_dir: Path,
                  check_obs: np.ndarray) -> Path:
    """Write ``policy.npz`` and ``policy.json`` of ``module``'s actor into ``out_dir``,
    after checking the numpy network against ``module.forward_inference`` on ``check_obs``
    (raises ``AssertionError`` on a mismatch: a module layout this export does not know)."""
    import torch

    from agents.atomic import write_atomic

    cfg = dict(module.model_config)
    enc_prefix, head_prefix = _PREFIXES[(algo, bool(cfg.get("vf_share_layers", True)))]
    state = module.get_state()
    enc, head = _layers(state, enc_prefix), _layers(state, head_prefix)
    meta = {"format": FORMAT, "algo": algo, "env_id": env_id,
            "encoder_activation": cfg.get("fcnet_activation", "tanh"),
            "head_activation": cfg.get("head_fcnet_activation", "relu"),
            "n_encoder_layers": len(enc), "n_head_layers": len(head),
            "squashed": algo == "sac", "obs_dim": int(enc[0][0].shape[1]),
            "action_dim": int(head[-1][0].shape[0] // 2)}
    arrays = {f"encoder_{i}_{p}": a for i, (w, b) in enumerate(enc)
              for p, a in (("w", w), ("b", b))}
    arrays |= {f"head_{i}_{p}": a for i, (w, b) in enumerate(head)
               for p, a in (("w", w), ("b", b))}
    policy = _Network(meta, arrays)
    with torch.no_grad():
        out = module.forward_inference({"obs": torch.as_tensor(check_obs, dtype=torch.float32)})
    inputs = out["action_dist_inputs"].numpy()[:, :meta["action_dim"]]
    ref = np.tanh(inputs) if meta["squashed"] else inputs
    np.testing.assert_allclose(policy.raw(check_obs), ref, rtol=1e-4, atol=1e-5)
    buf = io.BytesIO()
    np.savez(buf, **arrays)
    out_dir.mkdir(parents=True, exist_ok=True)
    write_atomic(out_dir / "policy.npz", buf.getvalue())
    write_atomic(out_dir / "policy.json", json.dumps(meta, indent=2) + "\n")
    return out_dir / "policy.npz"


class _Network:
    """The actor as numpy: encoder layers (activation after each), head layers (activation
    after all but the last), the mean half of the output, tanh when squashed."""

    def __init__(self, meta: dict[str, Any], arrays: dict[str, np.ndarray]) -> None:
        self.meta = meta
        self.enc = [(arrays[f"encoder_{i}_w"], arrays[f"encoder_{i}_b"])
                    for i in range(meta["n_encoder_layers"])]
        self.head = [(arrays[f"head_{i}_w"], arrays[f"head_{i}_b"])
                     for i in range(meta["n_head_layers"])]
        self.f_enc = ACTIVATIONS[meta["encoder_activation"]]
        self.f_head = ACTIVATIONS[meta["head_activation"]]

    def raw(self, obs: np.ndarray) -> np.ndarray:
        x = np.atleast_2d(np.asarray(obs, np.float64))
        for w, b in self.enc:
            x = self.f_enc(x @ w.T + b)
        for i, (w, b) in enumerate(self.head):
            x = x @ w.T + b
            if i < len(self.head) - 1:
                x = self.f_head(x)
        mean = x[:, :self.meta["action_dim"]]
        return np.tanh(mean) if self.meta["squashed"] else mean


def load_network(path: Path) -> _Network:
    """The network of ``policy.npz`` (or a folder holding it) with its ``policy.json``."""
    npz = path / "policy.npz" if path.is_dir() else path
    meta_path = npz.with_suffix(".json")
    try:
        meta = json.loads(meta_path.read_text())
        with np.load(npz, allow_pickle=False) as data:
            arrays = {k: data[k] for k in data.files}
    except (OSError, ValueError) as exc:
        raise PolicyFileError(f"cannot read the policy {str(npz)!r} with "
                              f"{meta_path.name}: {exc}") from None
    if not isinstance(meta, dict) or meta.get("format") != FORMAT:
        raise PolicyFileError(f"{str(meta_path)!r} is not a food-fetch RLlib policy "
                              f"(format {FORMAT!r})")
    for key in ("encoder_activation", "head_activation"):
        if meta.get(key) not in ACTIVATIONS:
            raise PolicyFileError(f"{str(meta_path)!r}: unknown {key} {meta.get(key)!r}")
    try:
        return _Network(meta, arrays)
    except (KeyError, TypeError) as exc:
        raise PolicyFileError(f"the policy {str(npz)!r} lacks {exc}") from None


class RLlibPolicyAgent(Agent):
    """A policy exported by ``food-fetch train --backend rllib`` (deterministic action)."""

    def __init__(self, path: str | Path) -> None:
        super().__init__()
        self.path = Path(path)
        self.net = load_network(self.path)
        self.name = str(path)

    def act(self, obs: np.ndarray) -> np.ndarray:
        obs = np.asarray(obs, np.float64).ravel()
        if obs.shape[0] != self.net.meta["obs_dim"]:
            raise ValueError(f"observation of {obs.shape[0]} values; the policy "
                             f"{str(self.path)!r} takes {self.net.meta['obs_dim']}")
        return np.clip(self.net.raw(obs)[0], -1.0, 1.0).astype(np.float32)

    def describe(self) -> dict[str, Any]:
        return {"name": self.name, "kind": "rllib-policy", **{
            k: self.net.meta[k] for k in ("algo", "env_id", "squashed")}}
