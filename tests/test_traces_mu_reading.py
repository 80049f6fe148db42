"""benchmarks/traces_mu_reading.py: the committed run behind the table of
docs/traces_format.md ("How mu is read from a slide"), its summary recomputed from its
records, the claims the page makes of it, one food measured again, and a stopped run that
keeps its finished foods and resumes."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import pytest

import benchmarks.traces_mu_reading as bench
from benchmarks.reproducibility import committed_rtol
from benchmarks.traces_mu_reading import (
    BEGIN,
    END,
    NOISES,
    PAGE,
    SLIDES,
    finished_foods,
    food_records,
    food_task,
    summarize,
    table,
)
from fetch_env.food_space import REPORTING_SEED, sample_foods

DATA = Path(__file__).resolve().parents[1] / "docs" / "data" / "traces_mu_reading.json"
COMMITTED = json.loads(DATA.read_text())


def _row(slide: str, noise: float, reading: str) -> dict[str, float]:
    return next(r for r in COMMITTED["summary"]
                if (r["slide"], r["noise"], r["reading"]) == (slide, noise, reading))


def test_the_committed_summary_and_page_table_are_the_records() -> None:
    assert summarize(COMMITTED["records"]) == COMMITTED["summary"]
    page = PAGE.read_text()
    block = page[page.index(BEGIN) + len(BEGIN):page.index(END)]
    assert table(COMMITTED["summary"]) in block
    assert not COMMITTED["lost"]


@pytest.mark.parametrize("slide", SLIDES)
@pytest.mark.parametrize("noise", NOISES)
def test_the_slipping_level_reads_every_food_closer_than_the_study_plateau(
        slide: str, noise: float) -> None:
    """What the page says of the committed run: the default reading reads every food, with
    a smaller 90th percentile error than the study's plateau, intervals that cover mu on at
    least 90 % of the foods where the plateau's cover it on at most 54 %, and no food called
    reliable (the plateau calls 2-7 foods more than 5 % off reliable)."""
    slipping, plateau = _row(slide, noise, "slipping"), _row(slide, noise, "study")
    assert slipping["failed"] == 0 and slipping["foods"] == 64
    assert slipping["p90"] < plateau["p90"] / 2
    assert slipping["coverage"] >= 0.9 and plateau["coverage"] <= 0.54
    assert slipping["reliable"] == 0 and plateau["reliable_misses"] >= 2


def test_one_food_measured_again_gives_the_committed_readings() -> None:
    """Reporting food 0's two slides, with and without noise, simulated and read again:
    the committed readings (bit for bit where numpy runs the committed run's kernels)."""
    food = sample_foods(1, REPORTING_SEED)[0]
    again = food_records(food)
    committed = [r for r in COMMITTED["records"] if r["food"] == 0]
    assert len(again) == len(committed) == len(SLIDES) * len(NOISES)
    rtol = committed_rtol(1e-9)
    for measured, kept in zip(again, committed, strict=True):
        assert (measured["slide"], measured["noise"]) == (kept["slide"], kept["noise"])
        for reading in ("slipping", "study"):
            if "failed" in kept[reading]:
                assert "failed" in measured[reading]
                continue
            assert math.isclose(measured[reading]["mu"], kept[reading]["mu"], rel_tol=rtol,
                                abs_tol=0.0), (measured["slide"], measured["noise"], reading)


def _fake_pool(stop_after: int | None) -> Any:
    """A stand-in for run_streamed that "finishes" foods at once (two readings each, one
    slide), streaming each as the real pool does, and stops after ``stop_after`` of them."""
    def run(fn: Any, tasks: list[tuple[Any, ...]], workers: int, jsonl: Path,
            entries: list[dict[str, Any]], report: Any) -> str:
        with jsonl.open("a") as log:  # last food first: the JSON must be in food order
            for i, (food,) in enumerate(reversed(tasks)):
                if stop_after is not None and i == stop_after:
                    return "interrupted (SIGTERM)"
                entry = {"food": food.index, "records": [
                    {"food": food.index, "slide": "study", "noise": noise,
                     **{r: {"mu": food.mu, "error": 0.0, "covered": True, "reliable": False}
                        for r in ("slipping", "study")}} for noise in NOISES]}
                log.write(json.dumps(entry) + "\n")
                entries.append(entry)
                report(i + 1, entry)
        return ""
    return run


def test_a_stopped_run_keeps_its_foods_and_resume_finishes_them(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    """Stopped after 2 of 5 foods: exit 143, the 2 in the .jsonl, no JSON written, one line
    on stderr saying so; --resume runs only the other 3 and writes all 5 in food order."""
    out = tmp_path / "mu.json"
    monkeypatch.setattr(bench, "run_streamed", _fake_pool(stop_after=2))
    assert bench.main(["--n", "5", "--out", str(out)]) == 143
    assert not out.exists()
    assert sorted(finished_foods(out.with_suffix(".jsonl"))) == [3, 4]
    err = capsys.readouterr().err.strip()
    assert err.startswith("traces_mu_reading: interrupted (SIGTERM); 2 of 5 foods finished")
    with out.with_suffix(".jsonl").open("a") as log:  # a stop in mid-line
        log.write('{"food": 2, "rec')
    asked: list[int] = []

    def resumed(fn: Any, tasks: list[tuple[Any, ...]], *rest: Any) -> str:
        asked.extend(f.index for (f,) in tasks)
        return _fake_pool(None)(fn, tasks, *rest)

    monkeypatch.setattr(bench, "run_streamed", resumed)
    assert bench.main(["--n", "5", "--out", str(out), "--resume"]) == 0
    assert sorted(asked) == [0, 1, 2]
    written = json.loads(out.read_text())
    assert [r["food"] for r in written["records"]] == [i for i in range(5) for _ in NOISES]
    assert written["meta"]["resumed_foods"] == 2 and not written["lost"]


def test_a_line_cut_short_by_a_stop_runs_again(tmp_path: Path) -> None:
    jsonl = tmp_path / "mu.jsonl"
    jsonl.write_text('{"food": 3, "records": []}\n{"food": 4, "rec')
    assert sorted(finished_foods(jsonl)) == [3]


def test_a_food_whose_readings_raise_is_kept_as_lost(monkeypatch: pytest.MonkeyPatch) -> None:
    def boom(food: Any) -> list[dict[str, Any]]:
        raise ValueError("bad slide")

    monkeypatch.setattr(bench, "food_records", boom)
    food = sample_foods(1, REPORTING_SEED)[0]
    assert food_task(food) == {"food": 0, "records": [], "lost": "ValueError: bad slide"}


@pytest.mark.parametrize("argv", [["--n", "0", "--out", "x.json"],
                                  ["--workers", "0", "--out", "x.json"], ["--out", "x.csv"],
                                  [], ["--out", "/proc/no/such/mu.json"]])
def test_bad_options_are_refused_before_any_work(
        argv: list[str], monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(bench, "run_streamed", lambda *a: pytest.fail("ran"))
    with pytest.raises(SystemExit) as exc:
        bench.main(argv)
    assert exc.value.code == 2
