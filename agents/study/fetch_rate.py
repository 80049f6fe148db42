"""The study's fetch findings, rerun on the simulator (``food-fetch reproduce fetch-rate``).

Runs the fetches of the study's scenes (docs/study.md, "Results the study reports"): a single row
of cubes at four spacings, two rows of soft or hard cubes at two clamp angles, diced soft
pieces at three clamp angles and diced mixes with hard pieces. Every scene is fixed (the
study's layouts, or diced mixes drawn from fixed seeds), so the table is reproducible.
:func:`run` returns ``fetch_rate.json`` (every number), ``fetch_rate_table.md`` (the table,
with the study's finding beside each group and whether the simulator agrees) and the figure
``figures/fetch_rate_summary.png``.
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from agents.study.report import StudyResult, progress, pyplot

# The study's fetch: clamp at 0.1 rad/s, lift 5 mm at 5 mm/s (docs/study.md, diced setup).
OMEGA = 0.1  # [rad/s]
LIFT_SPEED = 0.005  # [m/s]
LIFT_HEIGHT = 0.005  # [m]
HOLD = 1.0  # [s] hold at theta_d before the lift
AIR_HOLD = 1.0  # [s] hold in the air before counting
SINGLE_ROW_THETA = 0.045  # [rad] the study does not state it for the single row
N_DICED_MIXES = 3  # diced mixes with hard pieces, drawn from the seed on
LARGE_LE = 0.34  # the study's "no large deformation" limit


@dataclass(frozen=True)
class Case:
    group: str
    label: str
    theta_d: float
    scene: Callable[[], tuple[Any, ...]]


def cases(quick: bool = False, seed: int = 0) -> list[Case]:
    """The scenes and clamp angles of the study's fetch findings (diced mixes from
    ``seed``, ``seed + 1``, ``seed + 2``)."""
    from fetch_env.env_scenes import SCENE_PRESETS, _diced
    from fetch_env.layouts import single_row, two_rows
    from fetch_env.materials import PRESETS, STUDY_LEVELS

    out: list[Case] = []
    for s in (0.001, 0.0005, 0.0003, 0.0001):
        out.append(Case("single_row", f"{s * 1e3:g} mm", SINGLE_ROW_THETA,
                        lambda s=s: single_row(spacing_across=s)))
    for mat in ("soft-0.2MPa", "hard-200MPa"):
        for th in (0.0425, 0.045):
            out.append(Case("two_rows", f"{mat.split('-')[0]} {th:g} rad", th,
                            lambda mat=mat: two_rows(material=PRESETS[mat])))
    for th in (0.045, 0.085, 0.09):
        out.append(Case("diced_soft", f"{th:g} rad", th, SCENE_PRESETS["diced-soft"]))
    for k in range(1 if quick else N_DICED_MIXES):
        out.append(Case("diced_mix", f"mix seed {seed + k} 0.085 rad", 0.085,
                        _diced(STUDY_LEVELS, seed=seed + k, n=6)))
    return out


STUDY: dict[str, str] = {
    "single_row": "fetch rate highest at the tightest spacing (0.1 mm); no large plastic strain",
    "two_rows": "soft (0.2 MPa) fetched better than hard (200 MPa) at the same theta_d; best "
                "with LE < 0.34",
    "diced_soft": "0.045 rad: LE < 0.1 but pieces fall in the lift; 0.085: all fetched; 0.09: "
                  "all fetched, LE > 0.38 in the clamp (> 0.43 in the lift)",
    "diced_mix": "hard pieces escape during the clamp, lowering the fetch rate",
}


def columns(pieces: tuple[Any, ...]) -> list[dict[str, Any]]:
    """Pieces grouped into columns along the clamp direction (y), widest span first.

    Two pieces share a column when their x-intervals overlap by more than half the narrower
    one.  ``span_y`` is the column's extent along the clamp (outer surface to outer surface,
    gaps included): flat rigid blades closing along y touch the widest column first.
    """
    cols: list[list[int]] = []
    for i, p in enumerate(pieces):
        for col in cols:
            q = pieces[col[0]]
            overlap = min(p.x + p.extents[0] / 2, q.x + q.extents[0] / 2) - max(
                p.x - p.extents[0] / 2, q.x - q.extents[0] / 2)
            if overlap > 0.5 * min(p.extents[0], q.extents[0]):
                col.append(i)
                break
        else:
            cols.append([i])
    out = [{"pieces": c, "span_y": float(max(pieces[i].y + pieces[i].extents[1] / 2 for i in c)
                                         - min(pieces[i].y - pieces[i].extents[1] / 2
                                               for i in c))} for c in cols]
    return sorted(out, key=lambda c: -c["span_y"])


def run_case(case: Case) -> dict[str, Any]:
    """One fetch of ``case``; a diverged simulation is recorded, not raised."""
    from fetch_env.controller import FetchAction, FetchSimulator
    from fetch_env.errors import SimulationDivergedError

    pieces = case.scene()
    action = FetchAction(theta_d=case.theta_d, omega=OMEGA, lift_speed=LIFT_SPEED,
                         hold=HOLD, lift_height=LIFT_HEIGHT, air_hold=AIR_HOLD)
    row: dict[str, Any] = {"group": case.group, "label": case.label, "theta_d": case.theta_d,
                           "n_pieces": len(pieces),
                           "materials": sorted({p.material.name for p in pieces})}
    try:
        r = FetchSimulator(pieces).run("fetch", action)
    except SimulationDivergedError as exc:
        row["error"] = exc.one_line()
        return row
    hard = [p["young"] >= 5e6 for p in r.pieces]
    row.update(
        fetch_rate=r.fetch_rate, fetch_rate_mass=r.fetch_rate_mass,
        le_clamp=max(p["max_log_strain_clamp"] for p in r.pieces),
        le_lift=max(p["max_log_strain_lift"] for p in r.pieces),
        residual_plastic=max((p["residual_plastic_strain"] for p in r.pieces
                              if p["residual_plastic_strain"] is not None), default=None),
        fetched=[p["fetched"] for p in r.pieces], hard=hard,
        stalled_at=r.extra.get("stalled_at"), wall_time=r.wall_time,
        fetch_rate_hard=(float(np.mean([f for f, h in zip(
            [p["fetched"] for p in r.pieces], hard, strict=True) if h])) if any(hard)
            else None),
        fetch_rate_soft=(float(np.mean([f for f, h in zip(
            [p["fetched"] for p in r.pieces], hard, strict=True) if not h]))
            if not all(hard) else None))
    if case.group.startswith("diced"):
        # Which columns (along the clamp) the fetched pieces come from: with flat rigid
        # blades only the widest column is squeezed (the others are not touched, or barely).
        cols = columns(pieces)
        fetched = row["fetched"]
        for c in cols:
            c["n_fetched"] = int(sum(fetched[i] for i in c["pieces"]))
        widest = {i for c in cols if c["span_y"] >= cols[0]["span_y"] - 1e-4
                  for i in c["pieces"]}
        row["columns"] = cols
        row["fetched_only_widest_column"] = bool(
            any(fetched) and all(i in widest for i, f in enumerate(fetched) if f))
    return row


def verdicts(rows: list[dict[str, Any]]) -> dict[str, tuple[str, str]]:
    """Per group: (what the simulator shows, 'agrees' / 'disagrees' / 'partly')."""
    by: dict[str, list[dict[str, Any]]] = {}
    for r in rows:
        by.setdefault(r["group"], []).append(r)
    out: dict[str, tuple[str, str]] = {}

    def fr(r: dict[str, Any]) -> float:
        return float(r.get("fetch_rate", math.nan))

    if "single_row" in by:
        g = by["single_row"]
        best = max(fr(r) for r in g)
        tight = fr(g[-1])
        le = max(r.get("le_lift", math.nan) for r in g)
        ok = tight >= best and tight > min(fr(r) for r in g)
        out["single_row"] = (
            f"fetch rate {' / '.join(f'{fr(r):.2f}' for r in g)} at 1 / 0.5 / 0.3 / 0.1 mm; "
            f"max LE {le:.2f}",
            "agrees" if ok else ("partly" if tight >= best else "disagrees"))
    if "two_rows" in by:
        g = {r["label"]: r for r in by["two_rows"]}
        pairs = [(g.get(f"soft {th:g} rad"), g.get(f"hard {th:g} rad")) for th in (0.0425, 0.045)]
        better = [s is not None and h is not None and fr(s) > fr(h) for s, h in pairs]
        ties = [s is not None and h is not None and fr(s) == fr(h) for s, h in pairs]
        text = "; ".join(f"{th:g} rad soft {fr(s):.2f} (LE {s.get('le_lift', math.nan):.2f}) "
                         f"vs hard {fr(h):.2f}" for th, (s, h) in zip((0.0425, 0.045), pairs,
                                                                       strict=True)
                         if s is not None and h is not None)
        out["two_rows"] = (text, "agrees" if all(better) else
                           ("partly" if any(better) or all(ties) else "disagrees"))
    if "diced_soft" in by:
        g = {r["theta_d"]: r for r in by["diced_soft"]}
        a, b, c = g.get(0.045, {}), g.get(0.085, {}), g.get(0.09, {})
        checks = [fr(a) < 1 and a.get("le_clamp", 1) < 0.1, fr(b) == 1.0,
                  fr(c) == 1.0 and c.get("le_clamp", 0) > 0.38]
        text = "; ".join(f"{th:g} rad: fetch {fr(r):.2f}, LE clamp "
                         f"{r.get('le_clamp', math.nan):.2f} lift {r.get('le_lift', math.nan):.2f}"
                         for th, r in ((0.045, a), (0.085, b), (0.09, c)))
        out["diced_soft"] = (text, "agrees" if all(checks) else
                             ("partly" if any(checks) else "disagrees"))
    if "diced_mix" in by:
        g = by["diced_mix"]
        hard = [r["fetch_rate_hard"] for r in g if r.get("fetch_rate_hard") is not None]
        soft = [r["fetch_rate_soft"] for r in g if r.get("fetch_rate_soft") is not None]
        h, s = (float(np.mean(hard)) if hard else math.nan), (float(np.mean(soft)) if soft
                                                               else math.nan)
        done = [fr(r) for r in g if not math.isnan(fr(r))]  # a diverged mix has no rate
        diverged = f" ({len(g) - len(done)} diverged)" if len(done) < len(g) else ""
        text = (f"mean fetch rate {np.mean(done) if done else math.nan:.2f} over {len(done)} "
                f"of {len(g)} mixes{diverged}; hard "
                f"(>= 5 MPa) pieces {h:.2f}, soft pieces {s:.2f}")
        out["diced_mix"] = (text, "agrees" if h < s else "disagrees")
    return out


def table(rows: list[dict[str, Any]]) -> str:
    v = verdicts(rows)
    lines = ["| group | case | theta_d [rad] | fetch rate | LE clamp | LE lift | note |",
             "|---|---|---|---|---|---|---|"]
    for r in rows:
        if "error" in r:
            lines.append(f"| {r['group']} | {r['label']} | {r['theta_d']:g} | diverged | | | "
                         f"{r['error'][:60]} |")
            continue
        note = []
        if r.get("fetch_rate_hard") is not None and r.get("fetch_rate_soft") is not None:
            note.append(f"hard {r['fetch_rate_hard']:.2f}, soft {r['fetch_rate_soft']:.2f}")
        if r.get("stalled_at") is not None:
            note.append(f"motor stalled at {r['stalled_at']:.4f} rad")
        if r.get("columns"):
            c = r["columns"]
            note.append("columns (span mm: fetched/n) " + ", ".join(
                f"{x['span_y'] * 1e3:.1f}: {x['n_fetched']}/{len(x['pieces'])}" for x in c))
        lines.append(f"| {r['group']} | {r['label']} | {r['theta_d']:g} | "
                     f"{r['fetch_rate']:.2f} | {r['le_clamp']:.3f} | {r['le_lift']:.3f} | "
                     f"{'; '.join(note)} |")
    lines += ["", "| group | the study | this simulator | verdict |", "|---|---|---|---|"]
    for group, (text, verdict) in v.items():
        lines.append(f"| {group} | {STUDY[group]} | {text} | {verdict} |")
    return "\n".join(lines) + "\n"


def figure(rows: list[dict[str, Any]]) -> Any:
    """Fetch rate and the largest log strain of every case, one panel per group."""
    plt = pyplot()
    groups = list(dict.fromkeys(r["group"] for r in rows))
    fig, axes = plt.subplots(1, len(groups), figsize=(4 * len(groups), 3.6), squeeze=False)
    for ax, group in zip(axes[0], groups, strict=True):
        g = [r for r in rows if r["group"] == group]
        x = np.arange(len(g))
        ax.bar(x - 0.2, [r.get("fetch_rate", np.nan) for r in g], 0.4, label="fetch rate")
        ax.bar(x + 0.2, [max(r.get("le_clamp", np.nan), r.get("le_lift", np.nan)) for r in g],
               0.4, label="max LE")
        ax.axhline(LARGE_LE, color="k", lw=0.8, ls="--")
        ax.set_xticks(x, [r["label"] for r in g], rotation=30, ha="right", fontsize=8)
        ax.set_ylim(0, 1.05)
        ax.set_title(group)
    axes[0][0].legend(fontsize=8)
    fig.suptitle("Fetch rate and max log strain (dashed: LE = 0.34)")
    fig.tight_layout()
    return fig


HELP = ("the study's fetch findings: single row vs spacing, two rows soft vs hard, diced soft "
        "at 0.045/0.085/0.09 rad, diced mixes with hard pieces")


def run(quick: bool = False, seed: int = 0, with_figures: bool = True,
        show_progress: bool = False) -> StudyResult:
    """Fetch every case and judge each group against the study's finding.

    Args:
        quick: one diced mix instead of three.
        seed: seed of the first diced mix (the others ``seed + 1``, ``seed + 2``).
        with_figures: also draw the summary figure (needs matplotlib).
        show_progress: a tqdm bar over the fetches.
    """
    todo = cases(quick, seed)
    rows = [run_case(c) for c in progress(todo, show_progress, "fetch-rate", "fetch")]
    settings = {"omega": OMEGA, "lift_speed": LIFT_SPEED, "lift_height": LIFT_HEIGHT,
                "hold": HOLD, "air_hold": AIR_HOLD, "seed": seed}
    text = table(rows)
    result = StudyResult(summary=[text.rstrip("\n")])
    result.texts["fetch_rate.json"] = json.dumps(
        {"settings": settings, "rows": rows, "verdicts": verdicts(rows)}, indent=1,
        default=float)
    result.texts["fetch_rate_table.md"] = text
    if with_figures:
        result.figures["figures/fetch_rate_summary.png"] = figure(rows)
    return result
