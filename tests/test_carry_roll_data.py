"""The committed carry-roll data (benchmarks/carry_roll.py): summaries that match their
scenes, and the docs table generated from them."""

from __future__ import annotations

import json
import multiprocessing
import os
import signal
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from benchmarks.carry_roll import (  # noqa: E402
    DATA,
    DOC,
    HELD_OUT,
    MARK,
    summarize,
    table_markdown,
)

SETS = {"tuning": json.loads(DATA.read_text()), "held_out": json.loads(HELD_OUT.read_text())}


@pytest.mark.parametrize(("name", "env_id"), [(name, env_id) for name, data in SETS.items()
                                              for env_id in sorted(data["ids"])])
def test_each_summary_is_its_scenes(name: str, env_id: str) -> None:
    block = SETS[name]["ids"][env_id]
    assert block["summary"] == summarize(block["scenes"])
    assert block["summary"]["scenes"] == 40


def test_the_held_out_scenes_were_never_tuned_on() -> None:
    """The best constant actions were chosen on seeds 100-139 (benchmarks/theta_sweep.py);
    the held-out run uses the headroom's reporting seeds."""
    seeds = {name: {r["seed"] for block in data["ids"].values() for r in block["scenes"]}
             for name, data in SETS.items()}
    assert seeds["tuning"] == set(range(100, 140))
    assert seeds["held_out"].isdisjoint(range(0, 1000)) and len(seeds["held_out"]) == 40
    assert set(SETS["held_out"]["ids"]) == set(SETS["tuning"]["ids"])


def test_no_piece_the_light_touch_lifts_is_dropped_by_the_roll() -> None:
    """The finding docs/agents.md states: the roll to pi/2 drops no piece the fetch held on
    single pieces and rows; where it drops one from a packed plate, the plate moved 1 nm
    keeps it (the chaos, not the carry), and that happens on at most 2 plates of 40."""
    for data in SETS.values():
        for env_id, block in data["ids"].items():
            s = block["summary"]
            assert s["dropped_rolled_on_twin"] == 0, env_id
            if env_id != "FoodFetch-TwoRows-v2":
                assert s["held_then_dropped_rolled"] == 0, env_id
            assert s["scenes_changed"] <= 2, env_id
    dropped = [r for r in SETS["held_out"]["ids"]["FoodFetch-TwoRows-v2"]["scenes"]
               if "twin_held" in r]
    assert [r["seed"] for r in dropped] == [80018, 80022]


def test_the_docs_table_is_generated_from_the_data() -> None:
    text = DOC.read_text()
    body = text.split(MARK[0], 1)[1].split(MARK[1], 1)[0]
    assert body.strip() == table_markdown().strip()


def test_a_bad_worker_count_is_refused_in_one_line(capsys: pytest.CaptureFixture[str]) -> None:
    from benchmarks.carry_roll import main

    with pytest.raises(SystemExit) as exc:
        main(["--workers", "0", "--out", str(ROOT / "out" / "never.json")])
    assert exc.value.code == 2
    assert "--workers must be >= 1, got 0" in capsys.readouterr().err


def _scene_or_death(env_id: str, seed: int) -> dict:
    """A stand-in for ``roll_scene`` whose second scene's worker dies (as under the OOM
    killer)."""
    if seed == 101:
        os._exit(9)
    return {"seed": seed}


@pytest.mark.skipif(multiprocessing.get_start_method() != "fork",
                    reason="the stand-in reaches the worker only through a forked copy")
def test_a_dead_worker_ends_in_one_line_and_keeps_the_finished_scene(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    import benchmarks.carry_roll as carry_roll

    monkeypatch.setattr(carry_roll, "roll_scene", _scene_or_death)
    monkeypatch.setattr(carry_roll, "summarize", lambda scenes: {"scenes": len(scenes)})
    out = tmp_path / "roll.json"
    handlers = {sig: signal.getsignal(sig) for sig in (signal.SIGTERM, signal.SIGHUP)}
    try:  # main() installs its own SIGTERM and SIGHUP handlers
        code = carry_roll.main(["--env", "FoodFetch-Block-v1", "--seeds", "100:103",
                                "--workers", "1", "--out", str(out)])
    finally:
        for sig, handler in handlers.items():
            signal.signal(sig, handler)
    err = capsys.readouterr().err.strip()
    assert code == 1 and err.count("\n") == 0 and "a worker died" in err, err
    data = json.loads(out.read_text())
    assert data["complete"] is False
    assert data["ids"]["FoodFetch-Block-v1"]["scenes"] == [{"seed": 100}]
