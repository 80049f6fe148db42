"""benchmarks/traces_mu_reading.py: the committed run behind the table of
docs/traces_format.md ("How mu is read from a slide"), its summary recomputed from its
records, the claims the page makes of it, and one food measured again."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest

from benchmarks.reproducibility import committed_rtol
from benchmarks.traces_mu_reading import (
    BEGIN,
    END,
    NOISES,
    PAGE,
    SLIDES,
    food_records,
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
