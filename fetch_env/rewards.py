"""The environments' reward terms, computed from a fetch's per-piece outcome.

Two ways of charging damage, by env version:

* ``"worst"`` (the -v0 ids): the largest logarithmic strain of any piece, ``LE_max``, costs
  ``deformation_weight * min(1, max(0, LE_max - safe_log_strain))``; a piece that passed
  through a blade or the plate costs the whole weight.  One crushed die costs a whole
  9-piece plate as much as a crushed single block.
* ``"per_piece"`` (the -v1 ids): each piece's excess strain, capped at 1 as above, is
  weighted by the piece's share of the scene (by count, or by mass with ``by_mass``), so a
  crushed die in a plate of eight costs an eighth of a crushed block and damaging two
  pieces costs twice one.

The time term charges the fetch's duration ``theta_d / omega + hold + lift / lift_speed``:
a person waiting for a bite cares about it.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

DAMAGE_MODES: tuple[str, ...] = ("worst", "per_piece")


def piece_excess(piece: dict[str, Any], safe_log_strain: float) -> float:
    """One piece's strain above the safe level, in [0, 1] (1 if it passed through).

    A piece that passed through a blade or the plate was cut or crushed past what the
    simulator models (its strain is no measurement): it takes the whole unit.  Beyond one
    unit of LE a piece is crushed; a larger number would only add variance to the return.
    """
    if piece["passed_through"]:
        return 1.0
    le = max(piece["max_log_strain_clamp"], piece["max_log_strain_lift"])
    return min(max(0.0, le - safe_log_strain), 1.0)


def damage_excess(pieces: Sequence[dict[str, Any]], safe_log_strain: float, mode: str,
                  by_mass: bool = False) -> float:
    """The scene's damage in units of excess LE, in [0, 1]: the worst piece's or the
    share-weighted sum over pieces (see the module docstring)."""
    excess = [piece_excess(p, safe_log_strain) for p in pieces]
    if mode == "worst":
        return max(excess)
    if by_mass:
        total = sum(p["mass"] for p in pieces)
        return sum(e * p["mass"] / total for e, p in zip(excess, pieces, strict=True))
    return sum(excess) / len(excess)


def fetch_duration(theta_d: float, omega: float, hold: float, lift_height: float,
                   lift_speed: float) -> float:
    """The fetch's time from the start of the clamp to the end of the lift [s]."""
    return theta_d / omega + hold + lift_height / lift_speed
