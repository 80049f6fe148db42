"""The true values the probes are held against: the material's g1, tau1 and mu, and K1, K2,
B either nominal (``2 E A / l``) or from the piece's purely elastic twin clamped by the same
probe (:func:`elastic_stiffness`, the one definition the CLI, the validation harness and
the tests use)."""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from fetch_env.controller import FetchAction, FetchSimulator, SimResult
from fetch_env.errors import SimulationDivergedError, require_type
from fetch_env.layouts import Piece
from fetch_env.probes.config import ProbeConfig, _check_probe_args
from fetch_env.probes.placement import first_contact_angle, probe_angle
from fetch_env.probes.traces import _mean_moment
from fetch_env.scene import Geometry


def nominal_stiffness(piece: Piece) -> float:
    """Nominal instantaneous SLS stiffness K1 + K2 of a piece between the two faces [N/m].

    The study's equations give each half-spoon a displacement ``dx`` and the force ``F_n``
    on it; both faces squeeze the piece, so its compression is ``2 dx`` and
    ``F_n = (E A / l) 2 dx``: ``K = 2 E A / l`` with ``l`` the piece's width along the clamp
    and ``A`` its mid cross-section (the full face for a cube, the ellipse ``pi/4 w h``
    otherwise).  This ignores Poisson confinement and contact curvature, so it is a nominal
    scale, not what a perfect estimator must return: compare g_1, tau_1 and mu exactly and
    K1, K2, B as ratios.
    """
    require_type("piece", piece, Piece, "a Piece")
    ex, ey, ez = piece.extents
    area = ex * ez if piece.shape == "cube" else math.pi / 4 * ex * ez
    return 2.0 * piece.material.young * area / ey


def true_parameters(piece: Piece) -> dict[str, float]:
    """The oracle's values for a piece: K1, K2, B (nominal) and the material's mu, g1, tau1."""
    require_type("piece", piece, Piece, "a Piece")
    m = piece.material
    k = nominal_stiffness(piece)
    k2 = m.g1 * k
    return {"K1": k - k2, "K2": k2, "B": m.tau1 * k2, "mu": m.mu, "g1": m.g1, "tau1": m.tau1}


# Where the elastic twin is placed along the blade (x) for the true stiffness: at the
# centre, and where a chaotic contact event pushed it through a blade or the plate there (1
# of 256 reporting foods: a 20 mm, 0.23 MPa cube whose twin's held moment came out 800 times
# the food's, with a log strain of 11) or set it rattling between the blades (1 of 256: a
# 10 mm ellipsoid, :func:`_twin_fault`), a micrometre or two off, far below anything
# physical (a 1 um move of the same twins held them at 0.196 N m against 0.171 for the
# first food itself, and at 0.0339 N m against the second's peak of 0.0333).
TWIN_SHIFTS: tuple[float, ...] = (0.0, 1e-6, 2e-6, 3e-6)


def elastic_stiffness(piece: Piece, config: ProbeConfig,
                      geometry: Geometry | None = None) -> dict[str, float]:
    """The "true" instantaneous stiffness ``K1 + K2`` of a piece under the relaxation probe.

    One definition, used by ``food-fetch estimate``, the validation harness and the tests:
    the study's eq. 7 stiffness of the piece's purely elastic twin (the same piece with
    ``g1 = 0``) clamped by the same probe to the same angle, with the first-contact angle
    ``theta_c`` the faces reach the piece's rest surface at (:func:`first_contact_angle`):
    ``K_el = M_el cos(theta_d) / (L^2 (sin theta_d - sin theta_c))``, ``M_el`` the twin's held
    moment and ``theta_d`` the angle it was held at (the probe's, or where a stiff piece
    stalled the motor short of it).  Then ``K2 = g1 K_el``, ``K1 = (1 - g1) K_el`` and
    ``B = tau1 K2``.  Unlike a nominal ``2 E A / l`` this is what an exact estimator must
    return for this piece, shape and clamp (Poisson confinement, contact curvature and the
    contact's own compliance included); g1, tau1 and mu are the material's.  A twin that
    passes through a blade or the plate, or rattles between the blades
    (:func:`_twin_fault`), is clamped again a micrometre along the blade
    (:data:`TWIN_SHIFTS`).

    Raises:
        SimulationDivergedError: the twin was not held at any placement.

    Returns:
        ``{"K_el", "theta_c", "theta_d", "M_el"}`` (N/m, rad, rad, N m).
    """
    _check_probe_args(piece, config, geometry)
    hold = 0.5
    faults = []
    for shift in TWIN_SHIFTS:
        twin = dataclasses.replace(piece, x=shift, y=0.0,
                                   material=dataclasses.replace(piece.material, g1=0.0))
        sim = FetchSimulator((twin,), geometry, impratio=config.relaxation_impratio,
                             timestep=config.relaxation_timestep,
                             relaxation_contact_ratio=config.relaxation_contact_ratio)
        theta_c = first_contact_angle(sim.scene_for("relaxation"))[0]
        command = probe_angle(sim, config.strain, "relaxation")
        res = sim.run("relaxation", FetchAction(theta_d=command, omega=config.omega,
                                                hold=hold, settle=config.settle))
        late = res.traces["t"] > res.traces["t"][-1] - 0.5 * hold
        fault = _twin_fault(res, late)
        if fault is None:
            break
        faults.append(f"{1e6 * shift:g} um: {fault}")
    else:
        raise SimulationDivergedError(
            f"the elastic twin of this {piece.shape} was not held at any placement tried "
            f"along the blade ({'; '.join(faults)}): its true stiffness is undefined",
            res.scene, res.action.to_dict())
    tr = res.traces
    # The angle the twin was held at: the probe's, or where a stiff piece stalled the motor
    # short of it (the command it stalled on, as the estimators take theta_d).
    theta_d = float(tr["theta_cmd"][-1])
    m_el = float(np.mean(_mean_moment(tr)[late]))
    lever = float(res.geometry["L"])
    unit = lever**2 * (math.sin(theta_d) - math.sin(theta_c)) / math.cos(theta_d)
    return {"K_el": m_el / unit, "theta_c": theta_c, "theta_d": theta_d, "M_el": m_el}


# The most of the twin's late held samples on which one half-spoon may let go of it (its
# moment under a tenth of the other's) for the twin to count as held.
TWIN_MAX_LOST_SHARE = 0.1


def _twin_fault(res: SimResult, late: np.ndarray) -> str | None:
    """Why the elastic twin's clamp ``res`` does not define a stiffness, or None: it passed
    through a blade or the plate, or it rattles between the blades, one face letting go of
    it on more than ``TWIN_MAX_LOST_SHARE`` of the late hold's samples.

    Why the rattle: a purely elastic piece has none of the material's viscous damping, and
    a small, stiff round one can bounce between the faces for the whole hold while the
    food itself sits still (reporting food 179, a 10 mm, 0.42 MPa ellipsoid: its twin let
    go of the right face on every other sample, and their mean read K1 + K2 at 1.84 kN/m
    against 3.9-4.0 kN/m for the twin held a micrometre along the blade and 4.01 kN/m
    probed).  Of the 768 tuning and reporting twins, that one lost a face on more than one
    late sample; one soft cube's lost it on one sample of 25, while jiggling by +-5 %."""
    if res.pieces[0]["passed_through"]:
        return "it passed through a blade or the plate"
    left, right = res.traces["moment_left"][late], res.traces["moment_right"][late]
    lost = np.minimum(left, right) < 0.1 * np.maximum(left, right)
    if lost.mean() > TWIN_MAX_LOST_SHARE:
        return (f"it rattles between the blades, one face letting go of it on "
                f"{int(lost.sum())} of {lost.size} late held samples")
    return None


def true_parameters_exact(piece: Piece, config: ProbeConfig,
                          geometry: Geometry | None = None) -> dict[str, float]:
    """K1, K2, B from :func:`elastic_stiffness` and the material's mu, g1, tau1."""
    m = piece.material
    k_el = elastic_stiffness(piece, config, geometry)["K_el"]
    k2 = m.g1 * k_el
    return {"K1": k_el - k2, "K2": k2, "B": m.tau1 * k2, "mu": m.mu, "g1": m.g1, "tau1": m.tau1}
