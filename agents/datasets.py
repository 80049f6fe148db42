"""Record ``food-fetch evaluate``'s episodes as Minari datasets for offline RL.

One dataset per agent, ``NAME/AGENT-v0`` (``food-fetch/block/study-v0``), the layout of
Minari's own datasets (``mujoco/halfcheetah/expert-v0``: a namespace per task, one dataset
per behaviour policy): offline-RL methods and their papers name the policy that collected
the data, and ``minari.combine_datasets`` mixes them where a mixture is wanted.

Every episode is one fetch: ``observations`` holds the reset observation and the final one
(2 x 15), ``actions`` the one action (1 x 3), ``rewards``, ``terminations`` and
``truncations`` one value each; ``infos`` holds :data:`INFO_FLOATS`, :data:`INFO_FLAGS`
and ``info_json`` (the env's whole info as JSON, traces left out) for the reset (row 0)
and the step (row 1).  Each episode's Minari metadata holds its ``seed`` (the scene of
``env.reset(seed=seed)``, the seed evaluate gave the agent too), ``episode`` (its index in
the evaluation) and ``agent``; the dataset's ``env_spec`` holds the env id and kwargs, and
its metadata key ``food_fetch`` the run's settings.  Replaying ``actions[0]`` on
``gym.make(env_spec).reset(seed=seed)`` gives the recorded reward.

The workers only collect plain transitions (:func:`transition`); the parent writes them in
episode order, so any ``--workers`` gives the same dataset.  A dataset is written into a
hidden temporary folder under the Minari root and renamed into place when complete, so an
interrupted write leaves nothing under its id.
"""

from __future__ import annotations

import json
import math
import os
import re
import shutil
import tempfile
import warnings
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np

VERSION = 0  # the -vN of every id written; a new recording takes a new NAME or overwrites
DATA_FORMAT = "hdf5"  # minari[hdf5]: h5py only, where the arrow format needs pyarrow

# Scalar infos recorded at the reset (NaN there: nothing has happened) and after the step.
INFO_FLOATS: tuple[str, ...] = (
    "reward_fetch", "reward_deformation", "reward_time", "fetch_rate", "fetch_rate_mass",
    "max_log_strain", "episode_time", "theta_d", "omega", "lift_speed", "hold")
INFO_FLAGS: tuple[str, ...] = ("is_success", "passed_through", "diverged")
_APPLIED = ("theta_d", "omega", "lift_speed", "hold")  # from info["action_applied"]
_NAMESPACE = re.compile(r"[-\w]+(?:/[-\w]+)*", re.ASCII)


class DatasetError(Exception):
    """A dataset NAME that cannot be used, or an id already taken (one line)."""


# ------------------------------------------------------------------------------ ids
def agent_dataset_name(spec: str) -> str:
    """The dataset name of an agent: its name, or a saved model's file stem with every
    character Minari does not allow in a name replaced by ``_``."""
    stem = Path(spec).stem if spec.endswith(".zip") or "/" in spec else spec
    return re.sub(r"[^-\w]", "_", stem, flags=re.ASCII) or "model"


def dataset_ids(name: str, agents: Sequence[str]) -> dict[str, str]:
    """``{agent: "NAME/AGENT-v0"}``, checked with Minari's own id parser."""
    from minari.dataset.minari_dataset import parse_dataset_id

    if not _NAMESPACE.fullmatch(name) or len(name) < 2:
        raise DatasetError(f"{name!r} is not a Minari namespace: at least 2 characters, "
                           "letters, digits, - and _, parts separated by / (e.g. "
                           "food-fetch/block)")
    ids: dict[str, str] = {}
    for spec in agents:
        ds_id = f"{name}/{agent_dataset_name(spec)}-v{VERSION}"
        if ds_id in ids.values():
            raise DatasetError(f"two agents would share the dataset {ds_id}: give the "
                               "models different file names")
        if parse_dataset_id(ds_id) != (name, agent_dataset_name(spec), VERSION):
            raise DatasetError(f"{ds_id!r} does not read back as a Minari id")
        ids[spec] = ds_id
    return ids


def check_free(ids: dict[str, str], overwrite: bool) -> None:
    """Refuse an id that already holds a dataset (under ``MINARI_DATASETS_PATH``, else
    ``~/.minari/datasets``) unless ``overwrite``; before any episode runs."""
    from minari.storage.datasets_root_dir import get_dataset_path

    for ds_id in ids.values():
        path = get_dataset_path(ds_id)
        if path.exists() and not overwrite:
            raise DatasetError(f"dataset {ds_id} exists ({path}); --dataset-overwrite "
                               "replaces it")
        if path.exists() and not (path / "data").is_dir():
            raise DatasetError(f"{path} exists and is not a Minari dataset (a namespace?)")


# ------------------------------------------------------------------------------ in a worker
def _info_row(info: dict[str, Any]) -> dict[str, Any]:
    applied = info.get("action_applied", {})
    row: dict[str, Any] = {}
    for key in INFO_FLOATS:
        value = applied.get(key) if key in _APPLIED else info.get(key)
        row[key] = math.nan if value is None else float(value)
    row["is_success"] = bool(info.get("is_success", False))
    row["passed_through"] = bool(info.get("passed_through", False))
    row["diverged"] = "error" in info
    row["info_json"] = json.dumps({k: v for k, v in info.items() if k != "traces"},
                                  default=str)
    return row


def transition(obs: np.ndarray, reset_info: dict[str, Any], action: np.ndarray,
               next_obs: np.ndarray, reward: float, terminated: bool, truncated: bool,
               info: dict[str, Any]) -> dict[str, Any]:
    """One episode's data as plain arrays (cheap to send from a worker process)."""
    rows = [_info_row(reset_info), _info_row(info)]
    return {
        "observations": np.stack([np.asarray(obs), np.asarray(next_obs)]),
        "actions": np.asarray(action)[None],
        "rewards": np.array([reward], dtype=np.float64),
        "terminations": np.array([terminated]), "truncations": np.array([truncated]),
        "infos": {k: [r[k] for r in rows] for k in rows[0]},
    }


def pop_transitions(records: list[dict[str, Any]]) -> dict[tuple[str, int], dict[str, Any]]:
    """Take the transitions out of evaluate's records (which then stay JSON data)."""
    return {(r["agent"], r["episode"]): r.pop("transition")
            for r in records if "transition" in r}


# ------------------------------------------------------------------------------ writing
@contextmanager
def _datasets_root(path: Path) -> Iterator[None]:
    """Minari writes under ``MINARI_DATASETS_PATH``: point it at ``path`` for a while."""
    old = os.environ.get("MINARI_DATASETS_PATH")
    os.environ["MINARI_DATASETS_PATH"] = str(path)
    try:
        yield
    finally:
        if old is None:
            del os.environ["MINARI_DATASETS_PATH"]
        else:
            os.environ["MINARI_DATASETS_PATH"] = old


def _requirements() -> list[str]:
    """The versions that made the data (``recover_environment`` warns on a mismatch)."""
    from importlib.metadata import PackageNotFoundError, version

    out = []
    for pkg in ("food-fetch", "mujoco", "gymnasium"):
        try:
            out.append(f"{pkg}=={version(pkg)}")
        except PackageNotFoundError:
            pass
    return out


def _buffers(agent: str, records: Sequence[dict[str, Any]],
             transitions: dict[tuple[str, int], dict[str, Any]]) -> tuple[list[Any], list[dict]]:
    """The agent's episodes in evaluation order as Minari buffers, and their metadata."""
    from minari.data_collector import EpisodeBuffer

    recs = sorted((r for r in records if r["agent"] == agent and
                   (agent, r["episode"]) in transitions), key=lambda r: r["episode"])
    buffers, meta = [], []
    for i, r in enumerate(recs):
        t = transitions[(agent, r["episode"])]
        buffers.append(EpisodeBuffer(
            id=i, seed=int(r["seed"]), observations=t["observations"], actions=t["actions"],
            rewards=list(t["rewards"]), terminations=list(t["terminations"]),
            truncations=list(t["truncations"]), infos=t["infos"]))
        meta.append({"episode": int(r["episode"]), "agent": agent})
    return buffers, meta


def write_dataset(ds_id: str, agent: str, env: Any, records: Sequence[dict[str, Any]],
                  transitions: dict[tuple[str, int], dict[str, Any]],
                  settings: dict[str, Any], overwrite: bool = False) -> int:
    """Write ``agent``'s recorded episodes as the Minari dataset ``ds_id``; the number of
    episodes written (none: nothing is written).

    Built in a hidden temporary folder under the Minari root (Minari's listing skips it)
    and renamed into place: an interrupted write leaves no dataset under ``ds_id``, and an
    overwritten one is replaced only once the new one is complete.
    """
    import minari
    from minari.namespace import create_namespace, list_local_namespaces
    from minari.storage.datasets_root_dir import get_dataset_path

    buffers, episode_meta = _buffers(agent, records, transitions)
    if not buffers:
        return 0
    final = get_dataset_path(ds_id)
    if final.exists() and not overwrite:
        raise DatasetError(f"dataset {ds_id} appeared during the run ({final}); not replaced")
    tmp = Path(tempfile.mkdtemp(prefix=".food-fetch-partial-", dir=get_dataset_path()))
    try:
        with _datasets_root(tmp), warnings.catch_warnings():
            # Minari asks for an author e-mail, a code link and an eval env: none apply
            warnings.filterwarnings("ignore", category=UserWarning, module=r"minari\.")
            ds = minari.create_dataset_from_buffers(
                ds_id, buffers, env=env, eval_env=env.spec, algorithm_name=agent,
                author="food-fetch evaluate", description=_description(agent, settings),
                requirements=_requirements(), data_format=DATA_FORMAT)
            ds.storage.update_metadata({"food_fetch": settings})
            ds.storage.update_episode_metadata(episode_meta)
        namespace = ds_id.rsplit("/", 1)[0]
        if namespace not in list_local_namespaces():
            create_namespace(namespace)
        if final.exists():  # overwrite: move the old one aside, deleted with tmp
            os.replace(final, tmp / "replaced")
        os.replace(tmp / ds_id, final)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return len(buffers)


def _description(agent: str, settings: dict[str, Any]) -> str:
    return (f"food-fetch evaluate: agent {agent!r} on {settings['env_id']} "
            f"(kwargs {settings['env_kwargs']}), episode i on env.reset(seed="
            f"{settings['seed']} + i); one step per episode. Replaying actions[0] on "
            "gym.make(env_spec).reset(seed=episode seed) gives the recorded reward.")
