"""The simulator against analytic answers: the checks the physics tests make, recorded.

Runs the same scenes and comparisons as the tests and writes simulated against analytic,
with the relative error and the test's bar, for the README's physics table
(``scripts/make_readme_tables.py``):

* the Prony law alone: a cube between rigid plates it sticks to, a 3 % step strain held
  4 tau_1; the plate force against E_0 (1 - nu) / ((1 + nu)(1 - 2 nu)) A eps
  [1 - g_1 (1 - exp(-t / tau_1))] at 0+, tau_1, 2 tau_1 and the end
  (``tests/test_material_law.py``, helper ``tests/plates.py``);
* the relaxation through the robot: the study's 0.2 MPa cube clamped to 0.0244 rad and held
  20 s; the hinge moment's overshoot M(t_d) / M_inf - 1 against the SLS solution
  (``tests/test_probes.py::relaxation_overshoot``);
* Coulomb friction: the induced slip, tangential / normal force on the half-spoons during the
  steady slide against the set mu (``tests/test_probes.py``);
* statics: in the air, the end-effector's vertical force against the weight of what is held:
  one soft cube, and a diced mix's fetched pieces (``tests/test_fetch.py``).

    python benchmarks/physics_checks.py --out docs/data/readme_physics.json
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks.readme_meta import meta, write_json
from fetch_env.controller import PHASE_CODE, FetchAction, FetchSimulator
from fetch_env.layouts import diced_mix, single_block
from fetch_env.materials import Material
from tests.plates import press
from tests.test_probes import relaxation_overshoot

GRAVITY = 9.81


def _case(label: str, simulated: float, analytic: float) -> dict[str, Any]:
    return {"case": label, "simulated": simulated, "analytic": analytic,
            "rel_error": simulated / analytic - 1}


def prony_law() -> list[dict[str, Any]]:
    """Plate force against the Prony law, three materials, four times each."""
    cases = []
    for g1, tau1, young in ((0.425, 3.667, 0.2e6), (0.6, 1.0, 0.2e6), (0.3, 2.0, 5e6)):
        mat = Material(young=young, g1=g1, tau1=tau1, poisson=0.3)
        size = 0.015
        t, force, strain = press(mat, size=size, strain=0.03)
        nu = mat.poisson
        p_wave = young * (1 - nu) / ((1 + nu) * (1 - 2 * nu))
        law = 1 - g1 * (1 - np.exp(-np.clip(t, 0, None) / tau1))
        for name, when in (("0+", 0.02), ("tau1", tau1), ("2 tau1", 2 * tau1), ("end", t[-1])):
            i = min(int(np.searchsorted(t, when)), len(t) - 1)
            cases.append(_case(f"E0 {young / 1e6:g} MPa, g1 {g1}, tau1 {tau1} s, at {name}",
                               float(force[i]), float(p_wave * size**2 * strain[i] * law[i])))
    return cases


def relaxation_through_the_robot() -> list[dict[str, Any]]:
    """Moment overshoot M(t_d) / M_inf - 1 against the SLS, at the study's clamp speeds."""
    cases = []
    for omega in (0.01, 0.02, 0.03, 0.04):
        measured, predicted = relaxation_overshoot(omega)
        cases.append(_case(f"omega {omega} rad/s", measured, predicted))
    return cases


def coulomb_friction() -> list[dict[str, Any]]:
    """Tangential / normal force during the steady induced slip against the set mu."""
    cases = []
    for mu in (0.1, 0.3, 0.5):
        r = FetchSimulator(single_block(material=Material(mu=mu))).run(
            "slip", FetchAction(theta_d=0.045, omega=0.1, hold=0.5, slide_time=10.0))
        tr = r.traces
        slide = np.flatnonzero(tr["phase"] == PHASE_CODE["slide"])
        steady = slide[len(slide) // 4: 3 * len(slide) // 4]
        normal = tr["normal_left"][steady] + tr["normal_right"][steady]
        tangential = tr["tangential_left"][steady] + tr["tangential_right"][steady]
        cases.append(_case(f"mu {mu}", float((tangential / normal).mean()), mu))
    return cases


def statics() -> list[dict[str, Any]]:
    """End-effector force in the air against the weight of the fetched pieces."""
    cube = single_block()
    r = FetchSimulator(cube).run("fetch", FetchAction(theta_d=0.045, hold=0.5))
    air = r.traces["phase"] == PHASE_CODE["air"]
    cases = [_case("15 mm soft cube, air-hold mean", float(-r.traces["force"][air][:, 2].mean()),
                   cube[0].mass * GRAVITY)]
    pieces = diced_mix(np.random.default_rng(7))
    r = FetchSimulator(pieces).run("fetch", FetchAction(theta_d=0.085))
    fetched = sum(p.mass for p, q in zip(pieces, r.pieces, strict=True) if q["fetched"])
    air = r.traces["phase"] == PHASE_CODE["air"]
    n_fetched = sum(q["fetched"] for q in r.pieces)
    cases.append(_case(f"diced mix 7 ({len(pieces)} pieces, {n_fetched} fetched), last 0.2 s",
                       float(-r.traces["force"][air][-20:, 2].mean()), fetched * GRAVITY))
    return cases


CHECKS = (
    ("prony_law", "Prony relaxation law, cube between rigid plates (force)", prony_law, 0.03,
     "tests/test_material_law.py"),
    ("relaxation_robot", "SLS relaxation through the robot (moment overshoot)",
     relaxation_through_the_robot, 0.10, "tests/test_probes.py"),
    ("coulomb", "Coulomb friction in an induced slip (tangential / normal)", coulomb_friction,
     0.02, "tests/test_probes.py"),
    ("statics", "Statics in the air (end-effector force / weight held)", statics, 0.01,
     "tests/test_fetch.py"),
)


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--out", type=Path, default=Path("docs/data/readme_physics.json"))
    args = p.parse_args()
    info = meta()
    start = time.perf_counter()
    checks = []
    for key, title, run, bar, test in CHECKS:
        t = time.perf_counter()
        cases = run()
        worst = max(abs(c["rel_error"]) for c in cases)
        checks.append({"key": key, "check": title, "bar": bar, "test": test, "cases": cases,
                       "worst_abs_rel_error": worst, "wall_s": round(time.perf_counter() - t, 1)})
        print(f"{title}: worst |error| {100 * worst:.2f} % (bar {100 * bar:g} %), "
              f"{checks[-1]['wall_s']:.0f} s", flush=True)
    info["wall_s"] = round(time.perf_counter() - start, 1)
    write_json(args.out, {"meta": info, "checks": checks})
    print(f"wrote {args.out} in {info['wall_s']:.0f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
