"""Fixtures shared by the test modules."""

from __future__ import annotations

import pytest


@pytest.fixture
def no_simulation(monkeypatch: pytest.MonkeyPatch) -> None:
    """Any simulation fails the test: a rejected call must do no work."""
    from fetch_env.controller import FetchSimulator

    def refuse(*_a: object, **_k: object) -> None:
        raise AssertionError("simulated before the inputs were validated")

    monkeypatch.setattr(FetchSimulator, "run", refuse)
