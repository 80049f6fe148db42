"""The study's Figs. 5 and 6 (``food-fetch reproduce viscoelastic``).

A 15 mm, 0.2 MPa cube with g1 = 0.425, tau1 = 3.667 s is clamped to theta_d = 0.0244 rad at
omega 0.01 / 0.02 / 0.03 / 0.04 rad/s and held (``hold``, default 25 s; the study held 5 s, but
this simulator's clamp rise is not exactly the SLS's, so a longer hold is needed for 3 %).
Both estimators (full fit and the study's three-step) are fitted to the measured angle and the
moment averaged over both half-spoons.  :func:`run` returns

* the table ``viscoelastic``: per omega and method, K1, K2, B, g1, tau1 with errors and 95 %
  intervals, R^2 per phase (the study's R^2 beside);
* the table ``viscoelastic_trend``: K1, K2, B change from 0.01 rad/s, here and in the study;
* ``fig5_fits.png``: fitted curves over the simulated moment;
* ``fig6_parameters.png``: K1, K2, B against omega; g1 and tau1 against the truth.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from agents.study.report import StudyOptionError, StudyResult, Table, check_range, progress, pyplot

HELP = "Figs. 5-6: K1, K2, B, g1, tau1 from the moment at omega 0.01-0.04 rad/s"
OMEGAS: tuple[float, ...] = (0.01, 0.02, 0.03, 0.04)
THETA_D = 0.0244
G1, TAU1 = 0.425, 3.667
# docs/study.md: change of K1, K2, B from omega = 0.01 rad/s to 0.02 / 0.03 / 0.04 rad/s, in %.
STUDY_TREND = {
    "K1": (0.735, 6.618, 10.294),
    "K2": (1.105, 6.630, 10.497),
    "B": (0.752, 6.466, 10.286),
}
STUDY_R2_CLAMP = "0.99958 to 0.99972 (0.94151 at 0.02 rad/s)"
STUDY_R2_HOLD = "0.83645 to 0.86445"
STUDY_DEV = {"g1": (0.004, 0.941), "tau1": (0.006, 0.164)}
METHODS = {"full": "full fit", "three-step": "three-step"}


def _pct(x: float) -> str:
    return f"{100 * x:+.3f}" if np.isfinite(x) else "-"


def check(omegas: list[float], hold: float, noise: float, clamp_weight: float) -> None:
    """Every option checked (:class:`StudyOptionError`) before any simulation runs."""
    if not omegas:
        raise StudyOptionError("omegas", "is empty")
    for w in omegas:
        check_range("omegas values", w, 1e-3, 2.0, "rad/s")
    check_range("noise", noise, 0.0, 0.5)
    check_range("hold", hold, 0.5, 600.0, "s")
    check_range("clamp_weight", clamp_weight, 0.0, 1e6, lo_open=True)  # as food-fetch estimate


def run(omegas: tuple[float, ...] | list[float] = OMEGAS, hold: float = 25.0, noise: float = 0.0,
        clamp_weight: float = 0.3, seed: int = 0, show_progress: bool = False) -> StudyResult:
    """Clamp the study's cube at each omega, fit both estimators, compare with the study.

    Args:
        omegas: clamping angular velocities [rad/s], each in [0.001, 2].
        hold: hold at theta_d [s].
        noise: white noise on the moment, as a share of its peak.
        clamp_weight: full fit: weight of clamp samples relative to hold samples.
        seed: seed of that noise.
        show_progress: a tqdm bar over the runs.
    """
    omegas = [float(w) for w in omegas]
    check(omegas, hold, noise, clamp_weight)
    runs = _measure(omegas, hold, noise, clamp_weight, seed, show_progress)
    tables = [_parameters_table(runs, hold, clamp_weight), _trend_table(runs)]
    figures = {"fig5_fits.png": _fits_figure(runs), "fig6_parameters.png": _parameters_figure(runs)}
    return StudyResult(tables=tables, figures=figures, summary=_summary(runs))


def _measure(omegas: list[float], hold: float, noise: float, clamp_weight: float, seed: int,
             show_progress: bool) -> list[dict[str, Any]]:
    """One relaxation probe per omega, fitted by the full fit and by the three-step method."""
    from estimators import EstimationError, estimate_three_step
    from fetch_env.layouts import single_block
    from fetch_env.materials import PRESETS
    from fetch_env.study_probes import run_relaxation_probe

    pieces = single_block("cube", 0.015, PRESETS["soft-0.2MPa"])
    runs: list[dict[str, Any]] = []
    for omega in progress(omegas, show_progress, "relaxation runs", "run"):
        r = run_relaxation_probe(pieces, THETA_D, omega, hold, "full", noise, seed, clamp_weight)
        try:
            r["three"] = estimate_three_step(r["t"], r["theta"], r["M"], r["geometry"])
        except EstimationError as exc:
            r["three"], r["three_error"] = None, str(exc)
        r["omega"] = omega
        runs.append(r)
    return runs


def _truth() -> tuple[float, float]:
    """The study cube's g1 and tau1."""
    from fetch_env.materials import PRESETS

    m = PRESETS["soft-0.2MPa"]
    return m.g1, m.tau1


def _parameter_row(omega: float, method: str, est: Any) -> list[str]:
    """One estimate's row of the parameters table (errors against the study cube's truth)."""
    g1_true, tau1_true = _truth()
    gi = est.intervals.get("g1", (math.nan, math.nan))
    ti = est.intervals.get("tau1", (math.nan, math.nan))
    return [f"{omega:g}", METHODS[method], f"{est.K1:.1f}", f"{est.K2:.1f}", f"{est.B:.1f}",
            f"{est.g1:.4f}", _pct(est.g1 / g1_true - 1),
            f"[{gi[0]:.4f}, {gi[1]:.4f}]" if np.isfinite(gi[0]) else "-",
            f"{est.tau1:.4f}", _pct(est.tau1 / tau1_true - 1),
            f"[{ti[0]:.3f}, {ti[1]:.3f}]" if np.isfinite(ti[0]) else "-",
            f"{est.r2_clamp:.5f}", f"{est.r2_hold:.5f}", str(est.reliable)]


def _parameters_table(runs: list[dict[str, Any]], hold: float, clamp_weight: float) -> Table:
    """Per omega and method: K1, K2, B, g1, tau1 with errors, intervals and R^2."""
    g1_true, tau1_true = _truth()
    header = ["omega rad/s", "method", "K1 N/m", "K2 N/m", "B N s/m", "g1", "g1 error %",
              "g1 95 %", "tau1 s", "tau1 error %", "tau1 95 %", "R2 clamp", "R2 hold",
              "reliable"]
    rows = []
    for r in runs:
        for key, est in (("full", r["estimate"]), ("three-step", r.get("three"))):
            if est is None:
                rows.append([f"{r['omega']:g}", METHODS[key], *["failed"] + ["-"] * 11])
            else:
                rows.append(_parameter_row(r["omega"], key, est))
    title = (f"Figs. 5-6: theta_d {THETA_D} rad, hold {hold:g} s, full-fit clamp weight "
             f"{clamp_weight:g}, true g1 {g1_true}, tau1 {tau1_true} s. Study: g1 within "
             f"{STUDY_DEV['g1'][1]} %, tau1 within {STUDY_DEV['tau1'][1]} %; R2 clamp "
             f"{STUDY_R2_CLAMP}, hold {STUDY_R2_HOLD}")
    return Table("viscoelastic", header, rows, title)


def _trend_table(runs: list[dict[str, Any]]) -> Table:
    """K1, K2, B change with the clamping speed relative to the first omega, beside the
    study's change where the omegas are the study's."""
    trend_rows = []
    base = runs[0]
    for r in runs[1:]:
        row = [f"{base['omega']:g} -> {r['omega']:g}"]
        for name in ("K1", "K2", "B"):
            for key in ("estimate", "three"):
                e0, e1 = base.get(key), r.get(key)
                row.append(_pct(getattr(e1, name) / getattr(e0, name) - 1)
                           if e0 is not None and e1 is not None else "-")
            idx = (OMEGAS.index(r["omega"]) - 1
                   if (r["omega"] in OMEGAS and base["omega"] == OMEGAS[0]) else -1)
            row.append(f"{STUDY_TREND[name][idx]:+.3f}" if idx >= 0 else "-")
        trend_rows.append(row)
    header = ["omega change"] + [f"{n} % ({m})" for n in ("K1", "K2", "B")
                                 for m in ("full", "3-step", "study")]
    return Table("viscoelastic_trend", header, trend_rows,
                 "K1, K2, B change with clamping speed (relative to the first omega)")


def _fits_figure(runs: list[dict[str, Any]]) -> Any:
    """Fig. 5: the full fit's curve over each simulated moment."""
    plt = pyplot()
    n = len(runs)
    fig, axes = plt.subplots(1, n, figsize=(3.6 * n, 3.4), squeeze=False)
    for ax, r in zip(axes[0], runs, strict=True):
        ax.plot(r["t"], r["M"], color="0.6", lw=0.8, label="simulated (mean of blades)")
        if "fitted" in r:
            ax.plot(r["t"], r["fitted"], "r-", lw=1.2, label="full fit (eq. 4)")
        est = r["estimate"]
        title = f"omega {r['omega']:g} rad/s"
        if est is not None:
            title += f"\nR2 clamp {est.r2_clamp:.4f}, hold {est.r2_hold:.4f}"
        ax.set(xlabel="t from clamp start [s]", ylabel="M [N m]", title=title)
        ax.legend(fontsize=7)
    return fig


def _parameters_figure(runs: list[dict[str, Any]]) -> Any:
    """Fig. 6: K1, K2, B against omega (with the study's trend); g1, tau1 against the truth."""
    plt = pyplot()
    fig, ax = plt.subplots(1, 3, figsize=(13, 3.8))
    _plot_trend(ax[0], runs)
    for k, (name, true) in enumerate(zip(("g1", "tau1"), _truth(), strict=True)):
        _plot_against_truth(ax[k + 1], runs, name, true)
    return fig


def _plot_trend(ax: Any, runs: list[dict[str, Any]]) -> None:
    """K1, K2, B change from the first omega, both methods, and the study's."""
    w = np.array([r["omega"] for r in runs])
    for name, mk in (("K1", "o"), ("K2", "s"), ("B", "^")):
        for key, ls in (("estimate", "-"), ("three", ":")):
            ests = [r.get(key) for r in runs]
            if any(e is None for e in ests):
                continue
            v = np.array([getattr(e, name) for e in ests])
            ax.plot(w, 100 * (v / v[0] - 1), mk + ls,
                    label=f"{name} {'full' if key == 'estimate' else '3-step'}")
        if runs[0]["omega"] == OMEGAS[0]:
            ax.plot(OMEGAS, [0.0, *STUDY_TREND[name]], mk + "--", color="r", alpha=0.5,
                    label=f"{name} study")
    ax.set(xlabel="omega [rad/s]", ylabel="change from first omega [%]",
           title="K1, K2, B against clamping speed")
    ax.legend(fontsize=6, ncol=2)


def _plot_against_truth(a: Any, runs: list[dict[str, Any]], name: str, true: float) -> None:
    """``name`` (g1 or tau1) by both methods with intervals, the truth, 3 % and the study's."""
    for key, mk in (("estimate", "o"), ("three", "s")):
        ests = [(r["omega"], r.get(key)) for r in runs if r.get(key) is not None]
        x = np.array([e[0] for e in ests])
        y = np.array([getattr(e[1], name) for e in ests])
        iv = np.array([e[1].intervals.get(name, (math.nan, math.nan)) for e in ests])
        a.errorbar(x, y, yerr=[y - iv[:, 0], iv[:, 1] - y], fmt=mk, capsize=3,
                   label="full fit" if key == "estimate" else "three-step")
    a.axhline(true, color="k", lw=1, label="true")
    a.axhspan(true * 0.97, true * 1.03, color="g", alpha=0.12, label="3 % bar")
    dev = STUDY_DEV[name][1] / 100
    a.axhspan(true * (1 - dev), true * (1 + dev), color="r", alpha=0.15,
              label=f"study's deviation ({STUDY_DEV[name][1]} %)")
    a.set(xlabel="omega [rad/s]", ylabel=name, title=f"{name} against the truth")
    a.legend(fontsize=7)


def _summary(runs: list[dict[str, Any]]) -> list[str]:
    """One line per omega: the full fit's g1, tau1 and their errors, or why it failed."""
    g1_true, tau1_true = _truth()
    lines = []
    for r in runs:
        e = r["estimate"]
        if e is None:
            lines.append(f"omega {r['omega']:g}: full fit failed: {r['error']}")
            continue
        lines.append(f"omega {r['omega']:g}: g1 {e.g1:.4f} ({_pct(e.g1 / g1_true - 1)} %), tau1 "
                     f"{e.tau1:.4f} s ({_pct(e.tau1 / tau1_true - 1)} %), R2 clamp "
                     f"{e.r2_clamp:.4f}, hold {e.r2_hold:.4f}")
    return lines
