"""The committed carry-roll data (benchmarks/carry_roll.py): summaries that match their
scenes, and the docs table generated from them."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from benchmarks.carry_roll import DATA, DOC, MARK, summarize, table_markdown  # noqa: E402

DATA_JSON = json.loads(DATA.read_text())


@pytest.mark.parametrize("env_id", sorted(DATA_JSON["ids"]))
def test_each_summary_is_its_scenes(env_id: str) -> None:
    block = DATA_JSON["ids"][env_id]
    assert block["summary"] == summarize(block["scenes"])
    assert block["summary"]["scenes"] == 40


def test_no_piece_the_light_touch_lifts_is_dropped_rolled() -> None:
    """The finding docs/agents.md states: the roll to pi/2 drops nothing the fetch held."""
    for block in DATA_JSON["ids"].values():
        assert block["summary"]["held_then_dropped_rolled"] == 0


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
