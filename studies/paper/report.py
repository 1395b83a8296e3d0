"""The paper study's report: the statistics behind the paper's claims C1-C8 (``launchers/paper.sh``, Figs. 4, 5, 7
and 8), from its exported results (:mod:`rovermarl.analysis.results`), built on the tables and tests of
:class:`rovermarl.analysis.claims.Claims` (the statistics are described there). ``docs/REPRODUCTION.md`` quotes
``claims.md`` verbatim (a test checks it).

``python studies/paper/report.py RESULTS_DIR [--trust-config]`` writes ``claims.md`` and ``claims.json`` into
``RESULTS_DIR`` and prints the report. It needs every job of :data:`REQUIRED`.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from rovermarl.analysis import stats
from rovermarl.analysis.claims import Claims
from rovermarl.analysis.cli import Parser, one_line_errors
from rovermarl.analysis.levels import THRESHOLDS, quartile_times
from rovermarl.analysis.results import COUPLING_KINDS, ResultsError, load

PROG = "studies/paper/report.py"
FIXED = ("k=1", "k=2", "k=4", "homogeneous")
# the jobs (setup: labels) the claims C1-C8 read: the paper study's, Figs. 4, 5, 7 and 8
REQUIRED = {"solo": ("k=1", "k=2", "k=4", "homogeneous", "adaptive"),
            "duo": ("k=1", "k=2", "k=4", "homogeneous", "adaptive", "k=1 strict", "k=2 strict", "k=4 strict")}


class PaperClaims(Claims):
    """The claims report: :meth:`run` checks that every job of :data:`REQUIRED` is there, then each claim's section."""

    def c1_c3(self) -> None:
        self.lines += ["### C1-C3: setup solo", ""]
        self.table("solo")
        for other in ("k=2", "k=4", "homogeneous", "adaptive"):
            self.compare("C1", "solo", "k=1", other, "time:4")
        for other in ("k=4", "homogeneous"):
            self.compare("C3", "solo", "k=1", other, "final")
        k1, k2 = self.get("solo", "k=1"), self.get("solo", "k=2")
        if k1 is not None and k2 is not None:
            t1, t2 = k1.curves.first(4), k2.curves.first(4)
            ratio = stats.ratio_ci(t1, t2)
            self.note("C2", "time_ratio", f"solo, median generations to 4, k=2 / k=1: {ratio.fmt(3)}",
                      ratio.as_dict())
            q1, q2 = quartile_times(t1), quartile_times(t2)
            quart = [b / a if np.isfinite(a) and np.isfinite(b) else math.inf if np.isfinite(a) else math.nan
                     for a, b in zip(q1, q2, strict=True)]
            self.note("C2", "quartile_ratio", "solo, generations until 1/4, 1/2, 3/4 of the runs reach 4, k=2 / k=1: "
                      + ", ".join("never" if np.isinf(r) else "n/a" if np.isnan(r) else f"{r:.2f}" for r in quart),
                      [None if not np.isfinite(r) else r for r in quart])
        self.lines.append("")

    def c4_c6(self) -> None:
        self.lines += ["### C4-C6: setup duo", ""]
        self.table("duo")
        for a, b in (("k=1", "k=2"), ("k=1", "k=4"), ("k=1", "homogeneous"), ("k=2", "homogeneous")):
            self.compare("C4", "duo", a, b, "final")
        times = {r.label: stats.median_ci(r.curves.first(4)) for r in self.methods("duo")}
        self.note("C4", "time_to_4", "duo, median generations to 4 (the all-solo level): " +
                  "; ".join(f"{label} {t.fmt(None)}" for label, t in times.items()),
                  {label: t.as_dict() for label, t in times.items()})
        for a, b in (("homogeneous", "k=1"), ("homogeneous", "k=2"), ("k=2", "k=1")):
            self.compare("C4", "duo", a, b, "time:4")
        for k in ("k=1", "k=2", "k=4"):
            self.compare("C6", "duo", k, f"{k} strict", "final")
            self.compare("C6", "duo", k, f"{k} strict", "time:5")
        self.lines.append("")

    def c7(self) -> None:
        self.lines += ["### C7: EXP3-adaptive against the best fixed k", ""]
        for setup in ("solo", "duo"):
            thr = THRESHOLDS[setup]
            fixed = [r for r in (self.get(setup, k) for k in FIXED) if r is not None]
            if not fixed or self.get(setup, "adaptive") is None:
                continue
            best = min(fixed, key=lambda r: (np.median(r.curves.first(thr)), -np.median(self.values(r, "final"))))
            self.note("C7", f"best_fixed_{setup}", f"{setup}: best fixed method (median generations to {thr:g}): "
                      f"{best.label}", best.label)
            self.compare("C7", setup, "adaptive", best.label, f"time:{thr:g}")
            self.compare("C7", setup, "adaptive", best.label, "final")
        self.lines.append("")

    def c8(self) -> None:
        self.lines += ["### C8: phenotypic coupling under k=1", "",
                       "Per run, over its generations that mutated one rover: the share of the episodes in which at "
                       "least one other rover ends at a different POI (or none) than under the parent team. Median "
                       "over runs [bootstrap 95% CI]; in parentheses, the median over runs of the fraction of "
                       "updates with at least one such episode; n is the total number of updates.", "",
                       "| job | accepted, score rose | accepted, score equal | rejected | accepted (all) vs rejected |",
                       "|---|---|---|---|---|"]
        out = {}
        for r in sorted(self.jobs.values(), key=lambda r: (r.setup != "solo", r.name)):
            coupling = r.summary.get("coupling")
            if not coupling or not r.label.startswith("k=1"):
                continue
            row, per_kind = [], {}
            for kind in COUPLING_KINDS:
                runs = [c[kind] for c in coupling.values() if c[kind]["n"]]
                share = stats.median_ci([c["share"] for c in runs]) if runs else None
                anyf = float(np.median([c["any"] for c in runs])) if runs else None
                n = sum(c[kind]["n"] for c in coupling.values())
                row.append(f"{share.fmt(2)} ({anyf:.2f}), n={n:,}" if share else "none")
                per_kind[kind] = {"share": share.as_dict() if share else None, "any": anyf, "n": n}
            accepted = [a for c in coupling.values() if (a := _accepted_share(c)) is not None]
            rejected = [c["rejected"]["share"] for c in coupling.values() if c["rejected"]["n"]]
            test = stats.mann_whitney(accepted, rejected) if accepted and rejected else None
            row.append(test.fmt() if test else "-")
            self.lines.append(f"| {r.setup} {r.label} | " + " | ".join(row) + " |")
            out[f"{r.setup} {r.label}"] = per_kind | {"accepted_vs_rejected": test.as_dict() if test else None}
        self.data["C8"] = out
        self.lines.append("")

    def plateau(self) -> None:
        """Were the curves still rising? Medians at half and full budget, and the runs that rose in the second half."""
        half = self.budget // 2
        self.lines += ["### Still rising at the budget?", "",
                       f"| job | median score @{half:,} | median score @{self.budget:,} | runs that rose after "
                       f"{half:,} |", "|---|---|---|---|"]
        out = {}
        for setup in ("solo", "duo"):
            for r in self.methods(setup):
                at = r.curves.at([half, self.budget])
                rose = int((at[:, 1] > at[:, 0]).sum())
                self.lines.append(f"| {setup} {r.label} | {np.median(at[:, 0]):.4g} | {np.median(at[:, 1]):.4g} | "
                                  f"{rose}/{len(at)} |")
                out[f"{setup} {r.label}"] = {"median_half": float(np.median(at[:, 0])),
                                             "median_full": float(np.median(at[:, 1])), "rose": rose}
        self.data["plateau"] = out
        self.lines.append("")

    def missing(self) -> list[str]:
        """The jobs of :data:`REQUIRED` not in the results: ``duo k=2 strict``, or for a setup without any job
        ``every solo job (k=1, ...)``."""
        out = []
        for setup, labels in REQUIRED.items():
            gone = [label for label in labels if self.get(setup, label) is None]
            if len(gone) == len(labels) and not self.methods(setup):
                out.append(f"every {setup} job ({', '.join(labels)})")
            else:
                out += [f"{setup} {label}" for label in gone]
        return out

    def run(self) -> tuple[str, dict]:
        """The claims report (markdown) and its numbers; :class:`ResultsError` if a job of :data:`REQUIRED` is
        missing."""
        missing = self.missing()
        if missing:
            where = next(iter(self.jobs.values())).path.parent
            n = sum(map(len, REQUIRED.values()))
            raise ResultsError(f"{where}: the claims report needs the {n} jobs of the paper study "
                               f"(launchers/paper.sh); missing: {'; '.join(missing)}")
        self.lines += [f"Budget: {self.budget:,} generations (team evaluations) per run; scores at "
                       + ", ".join(f"{b:,}" for b in self.budgets) + " generations. 95% CIs in brackets.", ""]
        self.c1_c3()
        self.c4_c6()
        self.c7()
        self.c8()
        self.plateau()
        self.compute()
        return self.text(), self.data


def _accepted_share(c: dict) -> float | None:
    n = c["improved"]["n"] + c["neutral"]["n"]
    return sum((c[k]["share"] or 0.0) * c[k]["n"] for k in ("improved", "neutral")) / n if n else None


def claims(path: Path, trust: bool = False) -> tuple[str, dict]:
    """Compute the claims report of the results dir ``path``; writes ``claims.md`` and ``claims.json`` there."""
    c = PaperClaims(load(path), trust=trust)
    c.run()
    return c.write(path, "claims")


def main(argv=None) -> None:
    p = Parser(prog=PROG, description="The statistics of the paper's claims C1-C8 from the paper study's results.")
    p.add_argument("results", type=Path, help="results dir written by `python -m rovermarl.analysis export`, "
                   "e.g. results/paper")
    p.add_argument("--trust-config", dest="trust", action="store_true",
                   help="build a world plug-in the jobs' configs name (its module runs code; default: refused)")
    args = p.parse_args(argv)
    with one_line_errors(PROG):
        print(claims(args.results, args.trust)[0], end="")


if __name__ == "__main__":
    main()
