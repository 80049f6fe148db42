"""The probes' simulations run at once on several processes (``run_probes(workers=)``,
``food-fetch estimate --workers``): the serial numbers, errors raised in their serial order,
a dead worker said in one line."""

from __future__ import annotations

import os
import pickle

import pytest

from fetch_env.errors import InvalidParameterError, SimulationDivergedError
from fetch_env.layouts import single_block
from fetch_env.materials import Material
from fetch_env.parallel import WorkerLostError, outcome, run_ahead
from fetch_env.probes import PROBE_CALIBRATIONS, PROBE_PRESETS, run_probes
from tests.cli_helpers import assert_one_line_error, run_cli

# a small stiff ellipsoid: seven clamps and three slides of the repeated probes in ~1 s
PIECES = single_block("ellipsoid", 0.012, Material(young=8e5, g1=0.35, tau1=1.2, mu=0.4))


@pytest.mark.parametrize("noise", [0.0, 0.01])
def test_workers_give_the_serial_estimates(noise: float) -> None:
    """Two workers: every estimate, interval, diagnostic and warning equal to the serial
    run's, bit for bit (each simulation is deterministic; the noise is drawn afterwards)."""
    config, cal = PROBE_PRESETS["repeated"], PROBE_CALIBRATIONS["repeated"]
    serial = run_probes(PIECES, config, noise=noise, seed=4, calibration=cal)
    pooled = run_probes(PIECES, config, noise=noise, seed=4, calibration=cal, workers=2)
    assert pooled.estimates == serial.estimates
    assert pooled.intervals == serial.intervals
    assert pooled.warnings == serial.warnings
    assert pooled.details["diagnostics"] == serial.details["diagnostics"]
    assert pooled.reliable == serial.reliable
    assert pooled.visco_valid and pooled.friction_valid


@pytest.mark.parametrize("bad", [0, -1, 1.5, True, "2"])
def test_bad_workers_refused_before_any_work(bad: object) -> None:
    with pytest.raises(InvalidParameterError, match="workers"):
        run_probes(PIECES, PROBE_PRESETS["repeated"], workers=bad)  # type: ignore[arg-type]


def _square(x: int) -> int:
    return x * x


def _diverge(x: int) -> int:
    raise SimulationDivergedError(f"diverged at {x}", {"scene": x}, {"theta_d": 0.05})


def _die(x: int) -> int:
    os._exit(3)


def test_errors_come_back_in_their_place() -> None:
    """A task's error is returned in its place, whole (its scene and action too), and
    :func:`outcome` raises it; the other tasks' results are kept."""
    tasks = [(_square, (2,)), (_diverge, (7,)), (_square, (3,))]
    for workers in (1, 2):
        results = run_ahead(tasks, workers)
        assert results[0] == 4 and results[2] == 9
        with pytest.raises(SimulationDivergedError, match="diverged at 7") as info:
            outcome(results[1])
        assert info.value.scene == {"scene": 7} and info.value.action == {"theta_d": 0.05}


def test_simulation_diverged_error_pickles_whole() -> None:
    exc = pickle.loads(pickle.dumps(SimulationDivergedError("m", {"a": 1}, {"b": 2})))
    assert (str(exc), exc.scene, exc.action) == ("m", {"a": 1}, {"b": 2})


def test_a_dead_worker_is_one_clear_error() -> None:
    with pytest.raises(WorkerLostError, match="died mid-run"):
        run_ahead([(_die, (1,)), (_square, (2,))], 2)


def test_cli_workers(capsys: pytest.CaptureFixture[str]) -> None:
    """--workers outside the adaptive probes, or below 1: one line, exit 2."""
    code, _, err = run_cli(["estimate", "--probes", "study", "--workers", "2"], capsys)
    assert_one_line_error(code, err)
    assert "--workers 2 applies to the precise, repeated, measure probes" in err
    code, _, err = run_cli(["estimate", "--workers", "0"], capsys)
    assert_one_line_error(code, err)
