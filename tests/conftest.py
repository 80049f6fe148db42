"""Fixtures shared by the test modules."""

from __future__ import annotations

import os

import pytest
from hypothesis import HealthCheck, settings

# Hypothesis profiles: "ci" (the default) runs the examples each test states, derandomized
# (a failure reproduces) and without an example database; "slow" (HYPOTHESIS_PROFILE=slow)
# lets the fuzzing tests run many more, randomized (tests/test_fuzz.py scales its counts).
settings.register_profile("ci", derandomize=True, database=None, deadline=None,
                          suppress_health_check=[HealthCheck.too_slow])
settings.register_profile("slow", max_examples=1000, database=None, deadline=None,
                          suppress_health_check=[HealthCheck.too_slow])
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "ci"))


@pytest.fixture
def no_simulation(monkeypatch: pytest.MonkeyPatch) -> None:
    """Any simulation fails the test: a rejected call must do no work."""
    from fetch_env.controller import FetchSimulator

    def refuse(*_a: object, **_k: object) -> None:
        raise AssertionError("simulated before the inputs were validated")

    monkeypatch.setattr(FetchSimulator, "run", refuse)
