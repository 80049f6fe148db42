"""The study's virtual experiments, rerun on this simulator.

Each module holds one experiment as a function that computes and returns its tables, texts
and figures (:class:`agents.study.report.StudyResult`) and writes nothing:

* :func:`agents.study.friction.run`: Fig. 4, mu by induced slippage;
* :func:`agents.study.viscoelastic.run`: Figs. 5-6, K1, K2, B, g1, tau1 at four clamp speeds;
* :func:`agents.study.fetch_rate.run`: the fetch-rate findings (rows, two rows, diced mixes).

``food-fetch reproduce EXPERIMENT --out DIR`` runs one and writes what it returns.
"""

from agents.study.report import StudyOptionError, StudyResult, Table

__all__ = ["StudyOptionError", "StudyResult", "Table"]
