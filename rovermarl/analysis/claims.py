"""The statistics behind the paper's claims C1-C8 and the selectors report, from exported results
(:mod:`rovermarl.analysis.results`); ``docs/REPRODUCTION.md`` quotes ``claims.md`` verbatim (a test checks it).

Every statistic is over the runs (seeds) of a job: medians of the score at fixed budgets with percentile-bootstrap
95% CIs; the runs reaching a level as a count with a Wilson 95% CI; the median time to a level, censored at the
budget (a run that never gets there counts as ``never``); two-sided Mann-Whitney U between methods. The claims
report needs every job of :data:`REQUIRED` (what ``launchers/paper.sh`` runs); ``selectors`` takes any subset.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from rovermarl.analysis import stats
from rovermarl.analysis.levels import THRESHOLDS, optimum, quartile_times, setup_rank
from rovermarl.analysis.results import COUPLING_KINDS, Result, ResultsError, load
from rovermarl.record.outputs import atomic_open, write_json

FIXED = ("k=1", "k=2", "k=4", "homogeneous")
ORDER = ("k=1", "k=2", "k=3", "k=4", "homogeneous", "adaptive", "ucb1", "thompson", "egreedy", "exp3s", "schedule",
         "k=1 strict", "k=2 strict", "k=4 strict")
# the jobs (setup: labels) the claims C1-C8 read: the paper study's, Figs. 4, 5, 7 and 8
REQUIRED = {"solo": ("k=1", "k=2", "k=4", "homogeneous", "adaptive"),
            "duo": ("k=1", "k=2", "k=4", "homogeneous", "adaptive", "k=1 strict", "k=2 strict", "k=4 strict")}


class Claims:
    """Looks up exported jobs by (setup, label) and formats the statistics of each claim."""

    def __init__(self, results: list[Result], x: str = "generation", trust: bool = False):
        """``x``: measure budgets and times in generations (``generation``) or in team evaluations (``evals``: the
        initial team's included; methods that spend more than one per generation then line up). ``trust``: build a
        world plug-in a job's config names (``--trust-config``; its module runs code), else only rovermarl's own."""
        if x not in ("generation", "evals"):
            raise ValueError(f"x must be 'generation' or 'evals', got {x!r}")
        self.x, self.unit, self.trust = x, "generations" if x == "generation" else "team evaluations", trust
        self.jobs = {(r.setup, r.label): r for r in results}
        self.budget = max(int(self.evals(r, r.curves.generations)) for r in results)
        self.budgets = sorted({max(self.budget // 100, 1), max(self.budget // 10, 1), self.budget})
        self.data: dict = {"budget": self.budget, "budgets": self.budgets}
        self.lines: list[str] = []

    def get(self, setup: str, label: str) -> Result | None:
        return self.jobs.get((setup, label))

    def evals(self, r: Result, generations):
        """Generations of ``r`` on this report's axis: themselves, or the team evaluations spent by then."""
        g = np.asarray(generations, dtype=np.float64)
        return g if self.x == "generation" else 1 + float(r.summary.get("evals_per_generation", 1)) * g

    def generation_at(self, r: Result, budgets) -> np.ndarray:
        """The last generation of ``r`` within each budget on this report's axis."""
        b = np.asarray(budgets, dtype=np.float64)
        g = b if self.x == "generation" else (b - 1) / float(r.summary.get("evals_per_generation", 1))
        return np.clip(np.floor(g + 1e-9), 0, r.curves.generations).astype(np.int64)

    def first(self, r: Result, level: float) -> np.ndarray:
        """When each run of ``r`` first reached ``level``, on this report's axis (``inf``: never)."""
        return self.evals(r, r.curves.first(level))

    def methods(self, setup: str) -> list[Result]:
        found = [r for (s, _), r in self.jobs.items() if s == setup]
        return sorted(found, key=lambda r: (ORDER.index(r.label) if r.label in ORDER else len(ORDER), r.label))

    def setups(self) -> list[str]:
        names = dict.fromkeys(s for s, _ in self.jobs)
        return sorted(names, key=lambda s: (setup_rank(s), s))

    def levels(self, setup: str) -> tuple[float, float]:
        """(optimum, threshold) of a setup: the world's maximum return, and the paper's threshold (else that)."""
        best = optimum(self.methods(setup)[0].config(), self.trust)
        return best, THRESHOLDS.get(setup, best)

    # ---- building blocks --------------------------------------------------------------------------------------
    def table(self, setup: str, against: str | None = None) -> None:
        """Per method: median score at each budget (and the median held-out score of the final teams, when every
        job recorded one), runs reaching the optimum and threshold, time to threshold; with ``against``,
        Mann-Whitney U of each method's final scores and times against that method's."""
        opt, thr = self.levels(setup)
        heldout = all("heldout_score" in r.summary for r in self.methods(setup))
        base = self.get(setup, against) if against else None
        head = [f"median score @{b:,}" for b in self.budgets] + (["median held-out score"] if heldout else [])
        head += [f"runs reaching {level:g}" for level in dict.fromkeys((opt, thr))]
        head += [f"median {self.unit} to {thr:g}", f"1/4, 1/2, 3/4 of runs at {thr:g} by"]
        head += [f"final score vs {against}", f"{self.unit} to {thr:g} vs {against}"] if base else []
        self.lines += [f"| {setup}: method | " + " | ".join(head) + " |", "|---" * (len(head) + 1) + "|"]
        rows = {}
        for r in self.methods(setup):
            at = r.curves.at(self.generation_at(r, self.budgets))
            med = [stats.median_ci(at[:, i]) for i in range(len(self.budgets))]
            n = len(r.curves.seeds)
            reach = {level: stats.wilson(int(np.isfinite(r.curves.first(level)).sum()), n) for level in (opt, thr)}
            times = self.first(r, thr)
            t = stats.median_ci(times)
            held = stats.median_ci(list(r.summary["heldout_score"].values())) if heldout else None
            cells = [m.fmt(3) for m in med] + ([held.fmt(3)] if held else []) + [_count(w, n) for w in reach.values()]
            cells += [t.fmt(None), ", ".join("never" if np.isinf(q) else f"{q:,.0f}" for q in quartile_times(times))]
            if base is not None:
                tests = [stats.mann_whitney(self.values(r, w), self.values(base, w)) for w in ("final", f"time:{thr}")]
                cells += ["-" if r is base else f"p{stats.format_p(x.p)}, P(a>b)={x.effect:.2f}" for x in tests]
            self.lines.append(f"| {r.label} | " + " | ".join(cells) + " |")
            rows[r.label] = {"median_score": {str(b): m.as_dict() for b, m in zip(self.budgets, med, strict=True)},
                             **{f"reach_{level:g}": w.as_dict() | {"runs": n} for level, w in reach.items()},
                             f"time_to_{thr:g}": t.as_dict()}
            if held:
                rows[r.label]["median_heldout_score"] = held.as_dict()
        self.lines.append("")
        self.data.setdefault("tables", {})[setup] = rows

    def compare(self, claim: str, setup: str, a: str, b: str, what: str) -> stats.Test | None:
        """Mann-Whitney U of method ``a`` against ``b``: ``what`` is ``final`` or ``time:LEVEL``."""
        ra, rb = self.get(setup, a), self.get(setup, b)
        if ra is None or rb is None:
            return None
        test = stats.mann_whitney(self.values(ra, what), self.values(rb, what))
        self.lines.append(f"- {setup}, {_what(what)}: {a} vs {b}: {test.fmt()}")
        self.data.setdefault(claim, {}).setdefault("tests", []).append(
            {"setup": setup, "a": a, "b": b, "what": what, **test.as_dict()})
        return test

    def values(self, r: Result, what: str) -> np.ndarray:
        if what == "final":
            return r.curves.at([r.curves.generations])[:, 0]
        return self.first(r, float(what.split(":")[1]))

    def note(self, claim: str, key: str, text: str, value) -> None:
        self.lines.append(f"- {text}")
        self.data.setdefault(claim, {})[key] = value

    # ---- the claims ---------------------------------------------------------------------------------------------
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

    def compute(self) -> None:
        self.lines += ["### Compute", ""]
        jobs = self.jobs.values()
        totals = {"team_evals": sum(r.summary["compute"]["team_evals"] for r in jobs),
                  "agent_steps": sum(r.summary["compute"].get("agent_steps") or 0 for r in jobs),
                  "wall_time_s": sum(r.summary["compute"]["wall_time_s"] for r in jobs),
                  "runs": sum(len(r.curves.seeds) for r in jobs), "jobs": len(self.jobs)}
        exact = sum(len(r.curves.seeds) * (r.curves.generations + 1) for r in jobs)
        totals["team_evals_in_results"] = exact
        self.lines.append(f"- {totals['jobs']} jobs, {totals['runs']} runs of {self.budget:,} generations: "
                          f"{exact:,} team evaluations in the results (initial team + every generation).")
        self.lines.append(f"- Logged by the launches (each job's `invocations.jsonl`): {totals['team_evals']:,} team "
                          f"evaluations ({totals['agent_steps']:,} agent-steps), {totals['wall_time_s'] / 3600:.2f} h "
                          "of summed job wall time.")
        self.data["compute"] = totals
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

    def text(self) -> str:
        return "\n".join(self.lines).rstrip() + "\n"

    def write(self, path: Path, name: str) -> tuple[str, dict]:
        """Write the report as ``name.md`` and its numbers as ``name.json`` into the results dir ``path``."""
        text = self.text()
        with atomic_open(Path(path) / f"{name}.md", "w") as f:
            f.write(text)
        write_json(Path(path) / f"{name}.json", json.loads(json.dumps(self.data, default=float)))
        return text, self.data


def _accepted_share(c: dict) -> float | None:
    n = c["improved"]["n"] + c["neutral"]["n"]
    return sum((c[k]["share"] or 0.0) * c[k]["n"] for k in ("improved", "neutral")) / n if n else None


def _count(est: stats.Estimate, n: int) -> str:
    return f"{round(est.value * n)}/{n} [{est.low * n:.1f}, {est.high * n:.1f}]"


def _what(what: str) -> str:
    return "final score" if what == "final" else f"generations to {what.split(':')[1]}"


def selectors(path: Path, against: str = "adaptive", x: str = "generation", trust: bool = False) -> tuple[str, dict]:
    """The method comparison of the results dir ``path`` (the k-selectors, or any methods): per setup, every
    method's table row, with Mann-Whitney U against ``against`` (the paper's EXP3); writes ``selectors.md`` and
    ``selectors.json``. ``x="evals"`` measures budgets and times in team evaluations (see :class:`Claims`)."""
    c = Claims(load(path), x, trust)
    u = c.unit
    c.lines += [f"Budget: {c.budget:,} {u} per run; scores at " + ", ".join(f"{b:,}" for b in c.budgets) +
                f" {u}. 95% CIs in brackets; p: two-sided Mann-Whitney U against `{against}` (for "
                f"{u}, P(a>b) below 0.5 means faster; never-reached counts as slowest).", ""]
    for setup in c.setups():
        c.lines += [f"### {setup}", ""]
        c.table(setup, against)
    c.compute()
    return c.write(path, "selectors")


def claims(path: Path, trust: bool = False) -> tuple[str, dict]:
    """Compute the claims report of the results dir ``path``; writes ``claims.md`` and ``claims.json`` there."""
    c = Claims(load(path), trust=trust)
    c.run()
    return c.write(path, "claims")
