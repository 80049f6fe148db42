"""The study's Fig. 4: mu by induced slippage (``food-fetch reproduce friction``).

Cube, ellipsoid and sphere (15 mm, 0.2 MPa) at true mu 0.1 / 0.2 / 0.3 / 0.5: each is clamped to
0.06 rad at 0.1 rad/s, held 0.5 s, then the closed pair moves 5 mm toward the plate over
``--slide-time`` s (the study: 10 s); ``estimators.estimate_friction`` finds the steady slide and
returns mu with a 95 % interval.  :func:`run` returns the tables ``friction`` (per run, the
study's worst deviation at that mu beside ours) and ``friction_by_shape``, and the figure
``fig4_friction.png``.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np

from agents.study.report import StudyOptionError, StudyResult, Table, check_range, progress, pyplot

HELP = "Fig. 4: mu by induced slippage, cube/ellipsoid/sphere at mu 0.1/0.2/0.3/0.5"
SHAPES: tuple[str, ...] = ("cube", "ellipsoid", "sphere")
MUS: tuple[float, ...] = (0.1, 0.2, 0.3, 0.5)
# docs/study.md: max deviation of the estimated mu at each true mu (absolute, and in %).
STUDY_MAX_DEV = {
    0.1: (0.00132, 1.32),
    0.2: (0.00272, 1.36),
    0.3: (0.00400, 1.33),
    0.5: (0.00665, 1.33),
}
STUDY_SHAPE_ORDER = "ellipsoid > sphere > cube (largest deviation first)"
TOLERANCE = 0.014  # the study's worst case, 1.4 %


def check(shapes: list[str], mus: list[float], slide_time: float, noise: float) -> None:
    """Every option checked (:class:`StudyOptionError`) before any simulation runs."""
    if not shapes:
        raise StudyOptionError("shapes", "is empty")
    bad = [s for s in shapes if s not in SHAPES]
    if bad:
        raise StudyOptionError("shapes", f"has an unknown shape {bad[0]!r}; choose from "
                               f"{','.join(SHAPES)}")
    if not mus:
        raise StudyOptionError("mus", "is empty")
    for mu in mus:
        check_range("mus values", mu, 0.0, 2.0, lo_open=True)
    check_range("noise", noise, 0.0, 0.5)
    check_range("slide_time", slide_time, 0.0, 120.0, "s", lo_open=True)  # FetchAction's


def run(shapes: tuple[str, ...] | list[str] = SHAPES, mus: tuple[float, ...] | list[float] = MUS,
        slide_time: float = 10.0, noise: float = 0.0, seed: int = 0,
        show_progress: bool = False) -> StudyResult:
    """Estimate mu by induced slippage on each (shape, mu) and compare with the study.

    Args:
        shapes: piece shapes (15 mm, 0.2 MPa).
        mus: true friction coefficients, each in (0, 2].
        slide_time: duration of the 5 mm slide [s] (the study: 10 s).
        noise: white noise on the contact forces, as a share of their peak.
        seed: seed of that noise.
        show_progress: a tqdm bar over the runs.
    """
    shapes, mus = list(shapes), [float(m) for m in mus]
    check(shapes, mus, slide_time, noise)
    results = _measure(shapes, mus, slide_time, noise, seed, show_progress)
    table = _results_table(results)
    by_shape, order = _by_shape_table(results, shapes)
    n_ok = sum(1 for row in table.rows if row[6] == "yes")
    summary = [f"friction: {n_ok}/{len(table.rows)} runs within 1.4 % of the true mu; "
               f"largest deviation by shape: {' > '.join(order)} (study: {STUDY_SHAPE_ORDER})"]
    return StudyResult(tables=[table, by_shape],
                       figures={"fig4_friction.png": _figure(results, shapes, mus)},
                       summary=summary)


def _measure(shapes: list[str], mus: list[float], slide_time: float, noise: float, seed: int,
             show_progress: bool) -> list[dict[str, Any]]:
    """One slip probe per (shape, mu): the estimate (None on failure) and the run's facts."""
    from fetch_env.layouts import single_block
    from fetch_env.materials import PRESETS
    from fetch_env.study_probes import run_slip_probe

    results: list[dict[str, Any]] = []
    jobs = [(s, m) for s in shapes for m in mus]
    for shape, mu in progress(jobs, show_progress, "friction runs", "run"):
        material = dataclasses.replace(PRESETS["soft-0.2MPa"], mu=mu)
        r = run_slip_probe(single_block(shape, 0.015, material), slide_time=slide_time,
                           noise=noise, seed=seed)
        results.append({"shape": shape, "mu": mu, "est": r["estimate"], "error": r["error"],
                        "wall": r["wall_sim"], "le": r["max_log_strain"]})
    return results


def _results_table(results: list[dict[str, Any]]) -> Table:
    """Per run: the estimate, its deviation and interval, beside the study's worst case."""
    header = ["shape", "true mu", "estimated mu", "deviation", "deviation %", "95 % interval",
              "within 1.4 %", "study max deviation at this mu", "reliable"]
    rows = []
    for r in results:
        est = r["est"]
        study = STUDY_MAX_DEV.get(r["mu"])
        study_s = f"{study[0]:.5f} ({study[1]:.2f} %)" if study else "-"
        if est is None:
            rows.append([r["shape"], f"{r['mu']:g}", "failed", "-", "-", "-", "no", study_s,
                         r["error"]])
            continue
        dev = est.mu - r["mu"]
        rows.append([r["shape"], f"{r['mu']:g}", f"{est.mu:.5f}", f"{dev:+.5f}",
                     f"{100 * dev / r['mu']:+.3f}",
                     f"[{est.interval[0]:.5f}, {est.interval[1]:.5f}]",
                     "yes" if abs(dev) <= TOLERANCE * r["mu"] else "no", study_s,
                     str(est.reliable)])
    return Table("friction", header, rows,
                 "Fig. 4: mu by induced slippage (15 mm, 0.2 MPa pieces)")


def _by_shape_table(results: list[dict[str, Any]], shapes: list[str]
                    ) -> tuple[Table, list[str]]:
    """Per shape, the largest and mean |deviation| (the study ranks shapes by the largest);
    and the shapes in that order."""
    by_shape = []
    for shape in shapes:
        devs = [abs(r["est"].mu / r["mu"] - 1) for r in results
                if r["shape"] == shape and r["est"] is not None]
        failed = sum(1 for r in results if r["shape"] == shape and r["est"] is None)
        by_shape.append([shape, f"{100 * max(devs):.3f}" if devs else "-",
                         f"{100 * float(np.mean(devs)):.3f}" if devs else "-", str(failed)])
    order = [row[0] for row in sorted((row for row in by_shape if row[1] != "-"),
                                      key=lambda row: -float(row[1]))]
    table = Table("friction_by_shape",
                  ["shape", "max abs deviation %", "mean abs deviation %", "failed runs"],
                  by_shape,
                  f"Deviation by shape. Here: {' > '.join(order)}; study: {STUDY_SHAPE_ORDER}")
    return table, order


def _figure(results: list[dict[str, Any]], shapes: list[str], mus: list[float]) -> Any:
    """Fig. 4: estimated against true mu with intervals; deviation here against the study's."""
    plt = pyplot()
    fig, ax = plt.subplots(1, 2, figsize=(11, 4.2))
    markers = {"cube": "s", "ellipsoid": "o", "sphere": "^"}
    for k, shape in enumerate(shapes):
        pts = [(r["mu"], r["est"]) for r in results if r["shape"] == shape and r["est"]]
        if not pts:
            continue
        x = np.array([p[0] for p in pts])
        y = np.array([p[1].mu for p in pts])
        lo = y - np.array([p[1].interval[0] for p in pts])
        hi = np.array([p[1].interval[1] for p in pts]) - y
        off = (k - 1) * 0.006
        ax[0].errorbar(x + off, y, yerr=[lo, hi], fmt=markers.get(shape, "o"), label=shape,
                       capsize=3)
        ax[1].plot(x + off, 100 * (y / x - 1), markers.get(shape, "o"), label=f"{shape} (here)")
    grid = np.linspace(0, max(mus) * 1.1, 10)
    ax[0].plot(grid, grid, "k--", lw=0.8, label="true")
    ax[0].set(xlabel="true mu", ylabel="estimated mu (95 % interval)",
              title="mu by induced slippage")
    sm = sorted(STUDY_MAX_DEV)
    ax[1].plot(sm, [STUDY_MAX_DEV[m][1] for m in sm], "r_", ms=18, mew=2,
               label="study: max |deviation|")
    ax[1].plot(sm, [-STUDY_MAX_DEV[m][1] for m in sm], "r_", ms=18, mew=2)
    ax[1].axhline(0, color="k", lw=0.5)
    ax[1].set(xlabel="true mu", ylabel="deviation [%]", title="deviation: here vs the study")
    for a in ax:
        a.legend(fontsize=8)
    return fig
