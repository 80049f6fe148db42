"""``food-fetch evaluate --dataset``: Minari datasets that ``minari.load_dataset`` opens, hold
what evaluate reported, replay to the recorded rewards and do not depend on ``--workers``."""

from __future__ import annotations

import importlib.util
import json
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import gymnasium as gym
import minari
import numpy as np
import pytest

from agents import evaluate as ev
from tests.cli_helpers import assert_one_line_error, interrupt_episode, run_cli

ENV_ID = "FoodFetch-Block-v0"
AGENTS = ("study", "random")
SEED, EPISODES = 40, 2
NAME = "food-fetch/block"  # recorded with 2 workers
NAME_ONE = "food-fetch/block-one-worker"  # the same run with 1 worker


def _evaluate(name: str, workers: int, js: Path) -> None:
    from agents.cli import main

    argv = ["evaluate", "--env", ENV_ID, *[x for a in AGENTS for x in ("--agent", a)],
            "--episodes", str(EPISODES), "--seed", str(SEED), "--workers", str(workers),
            "--quiet", "--json", str(js), "--json-episodes", "--dataset", name]
    assert main(argv) == 0


@pytest.fixture(scope="module")
def recorded(tmp_path_factory: pytest.TempPathFactory) -> Iterator[dict[str, Any]]:
    """The evaluation's JSON (with every episode) after recording both datasets."""
    root = tmp_path_factory.mktemp("minari")
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("MINARI_DATASETS_PATH", str(root))
        _evaluate(NAME, 2, root / "two.json")
        _evaluate(NAME_ONE, 1, root / "one.json")
        yield json.loads((root / "two.json").read_text())


def _episodes(ds: minari.MinariDataset) -> list[tuple[Any, dict[str, Any]]]:
    meta = ds.storage.get_episode_metadata(range(ds.total_episodes))
    return list(zip(ds.iterate_episodes(), meta, strict=True))


def test_one_dataset_per_agent_holds_what_evaluate_reported(recorded: dict[str, Any]) -> None:
    ids = {f"{n}/{a}-v0" for n in (NAME, NAME_ONE) for a in AGENTS}
    assert set(minari.list_local_datasets()) == ids
    for agent in AGENTS:
        ds = minari.load_dataset(f"{NAME}/{agent}-v0")
        assert ds.total_episodes == EPISODES and ds.total_steps == EPISODES
        settings = ds.storage.metadata["food_fetch"]
        assert settings["env_id"] == ENV_ID and settings["agent"] == agent
        assert settings["complete"] and settings["env_kwargs"] == {}
        assert ds.env_spec is not None and ds.env_spec.id == ENV_ID
        reported = sorted((r for r in recorded["episodes_detail"] if r["agent"] == agent),
                          key=lambda r: r["episode"])
        for (ep, meta), rec in zip(_episodes(ds), reported, strict=True):
            assert meta["seed"] == rec["seed"] == SEED + rec["episode"]
            assert meta["episode"] == rec["episode"] and meta["agent"] == agent
            assert ep.observations.shape == (2, 15) and ep.actions.shape == (1, 3)
            assert ep.rewards.tolist() == [rec["reward"]]
            assert ep.terminations.tolist() == [True] and ep.truncations.tolist() == [False]
            step = {k: v[1] for k, v in ep.infos.items()}
            assert step["theta_d"] == rec["theta_d"] and step["omega"] == rec["omega"]
            assert step["fetch_rate"] == rec["fetch_rate"]
            assert bool(step["is_success"]) == rec["is_success"]
            assert json.loads(step["info_json"])["fetch_rate"] == rec["fetch_rate"]
            assert np.isnan(ep.infos["reward_fetch"][0])  # the reset row: nothing happened yet


def test_episodes_replay_to_the_recorded_rewards(recorded: dict[str, Any]) -> None:
    """Observations are the env's, actions the agent's, and stepping the recorded action on
    ``reset(seed=episode seed)`` gives the recorded reward (exactly: the scene compiled after
    ``warm_up``, as in every evaluate process)."""
    ev.warm_up()
    for agent in AGENTS:
        ds = minari.load_dataset(f"{NAME}/{agent}-v0")
        env = gym.make(ds.storage.metadata["food_fetch"]["env_id"],
                       **ds.storage.metadata["food_fetch"]["env_kwargs"])
        policy = ev.make_agent(agent, ENV_ID)
        for ep, meta in _episodes(ds):
            obs, _ = env.reset(seed=meta["seed"])
            np.testing.assert_array_equal(obs, ep.observations[0])
            policy.seed(meta["seed"])
            policy.begin_episode(env)
            np.testing.assert_array_equal(np.asarray(policy.act(obs), np.float32),
                                          ep.actions[0])
            next_obs, reward, terminated, _, _ = env.step(ep.actions[0])
            assert reward == pytest.approx(ep.rewards[0], abs=1e-9)
            np.testing.assert_array_equal(next_obs, ep.observations[1])
            assert terminated
        env.close()


def test_any_worker_count_gives_the_same_dataset(recorded: dict[str, Any]) -> None:
    for agent in AGENTS:
        two = _episodes(minari.load_dataset(f"{NAME}/{agent}-v0"))
        one = _episodes(minari.load_dataset(f"{NAME_ONE}/{agent}-v0"))
        for (a, meta_a), (b, meta_b) in zip(two, one, strict=True):
            assert meta_a == meta_b
            for field in ("observations", "actions", "rewards", "terminations"):
                np.testing.assert_array_equal(getattr(a, field), getattr(b, field))
            assert a.infos.keys() == b.infos.keys()
            for key in a.infos:
                np.testing.assert_array_equal(a.infos[key], b.infos[key])


# (what the error names, the options that cause it)
@pytest.mark.parametrize("fragment, argv", [
    ("dataset food-fetch/taken/study-v0 exists", ["--dataset", "food-fetch/taken"]),
    ("'x' is not a Minari namespace", ["--dataset", "x"]),
    ("'a b' is not a Minari namespace", ["--dataset", "a b"]),
    ("is not a Minari namespace", ["--dataset", "/abs/name"]),
    ("is not a Minari namespace", ["--dataset", "ns/"]),
    ("--dataset-overwrite needs --dataset NAME", ["--dataset-overwrite"]),
])
def test_dataset_mistakes_exit_2_before_any_episode(
        argv: list[str], fragment: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    def refuse(_task: ev.Task) -> dict:
        raise AssertionError("an episode ran before the dataset name was checked")

    monkeypatch.setattr(ev, "run_episode", refuse)
    monkeypatch.setenv("MINARI_DATASETS_PATH", str(tmp_path))
    (tmp_path / "food-fetch" / "taken" / "study-v0" / "data").mkdir(parents=True)
    code, _out, err = run_cli(["evaluate", "--agent", "study", "--episodes", "1", *argv],
                              capsys)
    assert_one_line_error(code, err)
    assert fragment in err


def test_missing_extra_is_one_line(monkeypatch: pytest.MonkeyPatch,
                                   capsys: pytest.CaptureFixture[str]) -> None:
    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec",
                        lambda name, *a: None if name == "minari" else real(name, *a))
    monkeypatch.setattr(ev, "run_episode", lambda _t: pytest.fail("an episode ran"))
    code, _out, err = run_cli(["evaluate", "--agent", "study", "--episodes", "1",
                               "--dataset", "food-fetch/x"], capsys)
    assert_one_line_error(code, err)
    assert "needs the datasets extra" in err and "pip install -e '.[datasets]'" in err


def test_ctrl_c_writes_only_finished_episodes_and_never_half_a_dataset(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.setenv("MINARI_DATASETS_PATH", str(tmp_path))
    calls = interrupt_episode(monkeypatch, 3)
    argv = ["evaluate", "--agent", "study", "--episodes", "5", "--quiet", "--dataset", "ff/cc"]
    code, out, _ = run_cli(argv, capsys)
    assert code == 130 and "dataset (partial) ff/cc/study-v0 (2 episodes)" in out
    ds = minari.load_dataset("ff/cc/study-v0")
    assert ds.total_episodes == 2 and not ds.storage.metadata["food_fetch"]["complete"]
    assert ds.storage.metadata["food_fetch"]["episodes_planned"] == 5

    # Ctrl-C while the replacing dataset is being written: the old one stays as it was
    make = minari.create_dataset_from_buffers

    def interrupted(*args: Any, **kwargs: Any) -> Any:
        make(*args, **kwargs)
        raise KeyboardInterrupt

    monkeypatch.setattr(minari, "create_dataset_from_buffers", interrupted)
    calls["n"] = -10
    code, _, err = run_cli([*argv[:4], "1", *argv[5:], "--dataset-overwrite"], capsys)
    assert code == 130 and "interrupted" in err
    assert minari.load_dataset("ff/cc/study-v0").total_episodes == 2
    assert sorted(p.name for p in tmp_path.iterdir()) == ["ff"]  # no temporary folder left
