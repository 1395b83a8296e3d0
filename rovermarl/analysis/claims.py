"""Methods compared from exported results (:mod:`rovermarl.analysis.results`): :class:`Claims`, the tables and tests
of a claims report, and :func:`selectors`, the comparison of any methods against one (``python -m rovermarl.analysis
selectors``). The paper's claims C1-C8 are built on :class:`Claims` by its study's report (``studies/paper/report.py``).

Every statistic is over the runs (seeds) of a job: medians of the score at fixed budgets with percentile-bootstrap
95% CIs; the runs reaching a level as a count with a Wilson 95% CI; the median time to a level, censored at the
budget (a run that never gets there counts as ``never``); two-sided Mann-Whitney U between methods.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from rovermarl.analysis import stats
from rovermarl.analysis.levels import THRESHOLDS, optimum, quartile_times, setup_rank
from rovermarl.analysis.results import Result, load
from rovermarl.record.outputs import atomic_open, write_json

ORDER = ("k=1", "k=2", "k=3", "k=4", "homogeneous", "adaptive", "ucb1", "thompson", "egreedy", "exp3s", "schedule",
         "k=1 strict", "k=2 strict", "k=4 strict")


class Claims:
    """Looks up exported jobs by (setup, label) and formats the statistics of each claim: ``lines`` (markdown) and
    ``data`` (their numbers) grow with each table, test and note, then :meth:`write` saves both."""

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

    def text(self) -> str:
        return "\n".join(self.lines).rstrip() + "\n"

    def write(self, path: Path, name: str) -> tuple[str, dict]:
        """Write the report as ``name.md`` and its numbers as ``name.json`` into the results dir ``path``."""
        text = self.text()
        with atomic_open(Path(path) / f"{name}.md", "w") as f:
            f.write(text)
        write_json(Path(path) / f"{name}.json", json.loads(json.dumps(self.data, default=float)))
        return text, self.data


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
