"""``food-fetch reproduce viscoelastic``: the study's Figs. 5 and 6.

A 15 mm, 0.2 MPa cube with g1 = 0.425, tau1 = 3.667 s is clamped to theta_d = 0.0244 rad at
omega 0.01 / 0.02 / 0.03 / 0.04 rad/s and held (``--hold``, default 25 s; the study held 5 s, but
this simulator's clamp rise is not exactly the SLS's, so a longer hold is needed for 3 %).
Both estimators (full fit and the study's three-step) are fitted to the measured angle and the
moment averaged over both half-spoons.  Writes

* ``viscoelastic.csv``/``.md``: per omega and method, K1, K2, B, g1, tau1 with errors and 95 %
  intervals, R^2 per phase (the study's R^2 beside);
* ``viscoelastic_trend.md``: K1, K2, B change from 0.01 rad/s, here and in the study;
* ``fig5_fits.png``: fitted curves over the simulated moment;
* ``fig6_parameters.png``: K1, K2, B against omega; g1 and tau1 against the truth.
"""

from __future__ import annotations

import argparse
import math
from typing import Any

import numpy as np

from agents.cli_common import UsageError, finite

HELP = "Figs. 5-6: K1, K2, B, g1, tau1 from the moment at omega 0.01-0.04 rad/s"
OMEGAS: tuple[float, ...] = (0.01, 0.02, 0.03, 0.04)
THETA_D = 0.0244
G1, TAU1 = 0.425, 3.667
# PAPER.md: change of K1, K2, B from omega = 0.01 rad/s to 0.02 / 0.03 / 0.04 rad/s, in %.
STUDY_TREND = {
    "K1": (0.735, 6.618, 10.294),
    "K2": (1.105, 6.630, 10.497),
    "B": (0.752, 6.466, 10.286),
}
STUDY_R2_CLAMP = "0.99958 to 0.99972 (0.94151 at 0.02 rad/s)"
STUDY_R2_HOLD = "0.83645 to 0.86445"
STUDY_DEV = {"g1": (0.004, 0.941), "tau1": (0.006, 0.164)}
METHODS = {"full": "full fit", "three-step": "three-step"}


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--omegas",
        default=",".join(f"{w:g}" for w in OMEGAS),
        metavar="LIST",
        help="comma-separated clamping velocities [rad/s] (default: 0.01,...,0.04)",
    )
    p.add_argument(
        "--hold", type=finite(), default=25.0, metavar="S", help="hold at theta_d [s] (default: 25)"
    )
    p.add_argument(
        "--noise",
        type=finite(),
        default=0.0,
        metavar="FRACTION",
        help="white noise on the moment, fraction of its peak (default: 0)",
    )
    p.add_argument(
        "--clamp-weight",
        type=finite(),
        default=0.3,
        metavar="W",
        help="full fit: weight of clamp samples relative to hold samples (default: 0.3, as "
        "food-fetch estimate; 1 is ordinary least squares)",
    )


def parse_omegas(text: str) -> list[float]:
    out = []
    for s in (s.strip() for s in text.split(",")):
        if not s:
            continue
        try:
            v = float(s)
        except ValueError:
            raise UsageError(f"food-fetch reproduce: --omegas: not a number: {s!r}") from None
        if not (math.isfinite(v) and 1e-3 <= v <= 2.0):
            raise UsageError(
                f"food-fetch reproduce: --omegas values must be in [0.001, 2] rad/s, got {s}"
            )
        out.append(v)
    if not out:
        raise UsageError("food-fetch reproduce: --omegas is empty")
    return out


def check(args: argparse.Namespace) -> list[float]:
    """Every option validated (one-line ``UsageError``) before ``--out`` is created or the
    progress bar starts; returns the parsed omegas."""
    omegas = parse_omegas(args.omegas)
    if not 0.0 <= args.noise <= 0.5:
        raise UsageError(f"food-fetch reproduce: --noise must be in [0, 0.5], got {args.noise:g}")
    if not 0.5 <= args.hold <= 600:
        raise UsageError(f"food-fetch reproduce: --hold must be in [0.5, 600] s, got {args.hold:g}")
    if not 0.0 < args.clamp_weight <= 1e6:  # as food-fetch estimate
        raise UsageError(
            f"food-fetch reproduce: --clamp-weight must be in (0, 1e6], got {args.clamp_weight:g}"
        )
    return omegas


def _pct(x: float) -> str:
    return f"{100 * x:+.3f}" if np.isfinite(x) else "-"


def run(args: argparse.Namespace) -> int:
    from tqdm import tqdm

    from agents.cmd_estimate import run_relaxation_probe
    from agents.cmd_reproduce import pyplot, save_figure, write_table
    from estimators import EstimationError, estimate_three_step
    from fetch_env.layouts import single_block
    from fetch_env.materials import PRESETS

    omegas = check(args)
    material = PRESETS["soft-0.2MPa"]
    pieces = single_block("cube", 0.015, material)
    g1_true, tau1_true = material.g1, material.tau1
    runs: list[dict[str, Any]] = []
    for omega in tqdm(omegas, desc="relaxation runs", unit="run"):
        r = run_relaxation_probe(
            pieces, THETA_D, omega, args.hold, "full", args.noise, args.seed, args.clamp_weight
        )
        try:
            r["three"] = estimate_three_step(r["t"], r["theta"], r["M"], r["geometry"])
        except EstimationError as exc:
            r["three"], r["three_error"] = None, str(exc)
        r["omega"] = omega
        runs.append(r)
    header = [
        "omega rad/s",
        "method",
        "K1 N/m",
        "K2 N/m",
        "B N s/m",
        "g1",
        "g1 error %",
        "g1 95 %",
        "tau1 s",
        "tau1 error %",
        "tau1 95 %",
        "R2 clamp",
        "R2 hold",
        "reliable",
    ]
    rows = []
    for r in runs:
        for key, est in (("full", r["estimate"]), ("three-step", r.get("three"))):
            if est is None:
                rows.append([f"{r['omega']:g}", METHODS[key], *["failed"] + ["-"] * 11])
                continue
            gi = est.intervals.get("g1", (math.nan, math.nan))
            ti = est.intervals.get("tau1", (math.nan, math.nan))
            rows.append(
                [
                    f"{r['omega']:g}",
                    METHODS[key],
                    f"{est.K1:.1f}",
                    f"{est.K2:.1f}",
                    f"{est.B:.1f}",
                    f"{est.g1:.4f}",
                    _pct(est.g1 / g1_true - 1),
                    f"[{gi[0]:.4f}, {gi[1]:.4f}]" if np.isfinite(gi[0]) else "-",
                    f"{est.tau1:.4f}",
                    _pct(est.tau1 / tau1_true - 1),
                    f"[{ti[0]:.3f}, {ti[1]:.3f}]" if np.isfinite(ti[0]) else "-",
                    f"{est.r2_clamp:.5f}",
                    f"{est.r2_hold:.5f}",
                    str(est.reliable),
                ]
            )
    write_table(
        args.out,
        "viscoelastic",
        header,
        rows,
        f"Figs. 5-6: theta_d {THETA_D} rad, hold {args.hold:g} s, full-fit clamp weight "
        f"{args.clamp_weight:g}, true g1 {g1_true}, "
        f"tau1 {tau1_true} s. Study: g1 within {STUDY_DEV['g1'][1]} %, tau1 within "
        f"{STUDY_DEV['tau1'][1]} %; R2 clamp {STUDY_R2_CLAMP}, hold {STUDY_R2_HOLD}",
    )
    # Trend of K1, K2, B against omega, relative to the first omega.
    trend_rows = []
    base = runs[0]
    for r in runs[1:]:
        row = [f"{base['omega']:g} -> {r['omega']:g}"]
        for name in ("K1", "K2", "B"):
            for key in ("estimate", "three"):
                e0, e1 = base.get(key), r.get(key)
                row.append(
                    _pct(getattr(e1, name) / getattr(e0, name) - 1)
                    if e0 is not None and e1 is not None
                    else "-"
                )
            study = STUDY_TREND[name]
            idx = (
                OMEGAS.index(r["omega"]) - 1
                if (r["omega"] in OMEGAS and base["omega"] == OMEGAS[0])
                else -1
            )
            row.append(f"{study[idx]:+.3f}" if idx >= 0 else "-")
        trend_rows.append(row)
    write_table(
        args.out,
        "viscoelastic_trend",
        [
            "omega change",
            "K1 % (full)",
            "K1 % (3-step)",
            "K1 % (study)",
            "K2 % (full)",
            "K2 % (3-step)",
            "K2 % (study)",
            "B % (full)",
            "B % (3-step)",
            "B % (study)",
        ],
        trend_rows,
        "K1, K2, B change with clamping speed (relative to the first omega)",
    )
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
    save_figure(fig, args.out / "fig5_fits.png")
    fig, ax = plt.subplots(1, 3, figsize=(13, 3.8))
    w = np.array([r["omega"] for r in runs])
    for name, mk in (("K1", "o"), ("K2", "s"), ("B", "^")):
        for key, ls in (("estimate", "-"), ("three", ":")):
            ests = [r.get(key) for r in runs]
            if any(e is None for e in ests):
                continue
            v = np.array([getattr(e, name) for e in ests])
            ax[0].plot(
                w,
                100 * (v / v[0] - 1),
                mk + ls,
                label=f"{name} {'full' if key == 'estimate' else '3-step'}",
            )
        if base["omega"] == OMEGAS[0]:
            ax[0].plot(
                OMEGAS,
                [0.0, *STUDY_TREND[name]],
                mk + "--",
                color="r",
                alpha=0.5,
                label=f"{name} study",
            )
    ax[0].set(
        xlabel="omega [rad/s]",
        ylabel="change from first omega [%]",
        title="K1, K2, B against clamping speed",
    )
    ax[0].legend(fontsize=6, ncol=2)
    for k, (name, true) in enumerate((("g1", g1_true), ("tau1", tau1_true))):
        a = ax[k + 1]
        for key, mk in (("estimate", "o"), ("three", "s")):
            ests = [(r["omega"], r.get(key)) for r in runs if r.get(key) is not None]
            x = np.array([e[0] for e in ests])
            y = np.array([getattr(e[1], name) for e in ests])
            iv = np.array([e[1].intervals.get(name, (math.nan, math.nan)) for e in ests])
            a.errorbar(
                x,
                y,
                yerr=[y - iv[:, 0], iv[:, 1] - y],
                fmt=mk,
                capsize=3,
                label="full fit" if key == "estimate" else "three-step",
            )
        a.axhline(true, color="k", lw=1, label="true")
        a.axhspan(true * 0.97, true * 1.03, color="g", alpha=0.12, label="3 % bar")
        dev = STUDY_DEV[name][1] / 100
        a.axhspan(
            true * (1 - dev),
            true * (1 + dev),
            color="r",
            alpha=0.15,
            label=f"study's deviation ({STUDY_DEV[name][1]} %)",
        )
        a.set(xlabel="omega [rad/s]", ylabel=name, title=f"{name} against the truth")
        a.legend(fontsize=7)
    save_figure(fig, args.out / "fig6_parameters.png")
    for r in runs:
        e = r["estimate"]
        if e is None:
            print(f"omega {r['omega']:g}: full fit failed: {r['error']}")
            continue
        print(
            f"omega {r['omega']:g}: g1 {e.g1:.4f} ({_pct(e.g1 / g1_true - 1)} %), tau1 "
            f"{e.tau1:.4f} s ({_pct(e.tau1 / tau1_true - 1)} %), R2 clamp {e.r2_clamp:.4f}, "
            f"hold {e.r2_hold:.4f}"
        )
    print(
        f"wrote {args.out / 'viscoelastic.md'}, viscoelastic.csv, viscoelastic_trend.md, "
        "fig5_fits.png, fig6_parameters.png"
    )
    return 0
