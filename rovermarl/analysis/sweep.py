"""Reading a sweep: its job dirs, their runs' score curves, and the labels that tell the methods apart.

A sweep's job dir holds ``summary.json``, ``.hydra/`` and ``runs/seed_XXX/curve.npz`` (when recorded, also
``behaviour.npz`` and ``occupancy.npz``); an exported one (:mod:`rovermarl.analysis.results`) reads the same way.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from omegaconf import OmegaConf

from rovermarl.analysis.curves import read_exported, read_run_arrays, read_run_curve
from rovermarl.analysis.levels import setup_rank
from rovermarl.env import World, make_world
from rovermarl.errors import PluginError, printable
from rovermarl.record.safe_read import RunSize, check_tree, read_json, read_yaml

# Config keys that never tell two methods apart (where and how a job runs; the setup, which figures group by), left
# out of labels. Kept by hand: conf/config.yaml's override_dirname.exclude_keys also drops `seeds` and is not exported.
NOT_METHOD = ("parallel", "ray", "hydra", "setup", "record", "checkpoint", "resume")

CREDIT_LABELS = {"global": "G", "difference": "D", "dpp": "D++"}   # algorithm.reward of the ccea baseline
RUN_DIR = re.compile(r"seed_\d+")   # a run's dir; seed_XXX.<hash> holds one set aside under another identity


class SweepError(Exception):
    """A path that holds no readable sweep, job or run; ``str(err)`` is one line."""


@dataclass
class RunCurve:
    """One run of a job: its dir, seed and score curve (and bandit probabilities)."""

    path: Path
    seed: int
    score: np.ndarray  # (G+1,) parent score after each generation
    probs: np.ndarray | None  # (G, K) bandit arm probabilities, None for fixed k
    probs_x: np.ndarray | None = None  # generations of the rows of probs (exported results), None: 0..G-1

    def has(self, name: str) -> bool:
        return (self.path / name).is_file()


@dataclass
class Job:
    """One job dir: a config (setup x method) and its runs."""

    path: Path
    choices: dict  # config group -> option name
    config: dict  # composed config (plain, unresolved)
    overrides: list[str]  # command-line overrides, quotes removed
    runs: list[RunCurve]
    finished: bool  # summary.json present

    @property
    def name(self) -> str:
        return self.path.name

    @property
    def setup(self) -> str:
        return printable(self.choices.get("setup") or (self.config.get("setup") or {}).get("name") or "default", 200)

    @property
    def strict(self) -> bool:
        selection = self.config.get("selection") or {}
        return bool(selection.get("strict", self.choices.get("selection") == "strict"))

    @property
    def bandit(self) -> bool:
        return any(r.probs is not None for r in self.runs)

    @property
    def homogeneous(self) -> bool:
        target = str((self.config.get("team") or {}).get("_target_", ""))
        return self.choices.get("team") == "homogeneous" or target.endswith("HomogeneousTeam")

    @property
    def k_name(self) -> str:
        """``k=2`` for a fixed k, else the k option name (``adaptive``)."""
        option = self.choices.get("k")
        k_cfg = self.config.get("k") or {}
        if option is None:
            option = k_cfg.get("value") if "value" in k_cfg else str(k_cfg.get("_target_", "k")).rsplit(".")[-1]
        return f"k={option}" if re.fullmatch(r"\d+", str(option)) else str(option)

    @property
    def algorithm(self) -> str:
        """The ``algorithm`` option (``cc11es`` for configs from before the group)."""
        return str(self.choices.get("algorithm") or "cc11es")

    @property
    def base_label(self) -> str:
        """``k=1``, ``adaptive``, ``homogeneous`` for CC-(1+1)-ES; another algorithm's name, with its reward if it
        has one (``ccea D++``)."""
        if self.algorithm != "cc11es":
            reward = (self.config.get("algorithm") or {}).get("reward")
            return self.algorithm + (f" {CREDIT_LABELS.get(reward, reward)}" if reward else "")
        return "homogeneous" if self.homogeneous else self.k_name

    @property
    def evals_per_generation(self) -> float:
        """Team evaluations per generation, as the job's ``summary.json`` records it; for jobs from before that key,
        from the runs' ``team_evals`` series if they record one, else 1."""
        given = (_read(self.path / "summary.json", "summary") or {}).get("evals_per_generation")
        if given is not None:
            return float(given)
        for run in self.runs[:1]:
            if run.has("curve.npz"):
                curve = read_run_arrays(run.path, self.size)
                if "team_evals" in curve and len(curve["team_evals"]):
                    return float(curve["team_evals"][-1] - 1) / len(curve["team_evals"])
        return 1.0

    @property
    def size(self) -> RunSize:
        """What the job's config implies of its runs' files (checked before they are read)."""
        return RunSize.of(self.config)

    def evals(self, generations) -> np.ndarray:
        """Team evaluations spent after ``generations`` (the initial team's one included)."""
        return 1 + self.evals_per_generation * np.asarray(generations, dtype=np.float64)

    @property
    def label(self) -> str:
        """The method on its own: ``base_label``, plus `` strict`` for strict selection."""
        return self.base_label + (" strict" if self.strict else "")

    def sort_key(self) -> tuple:
        k = self.k_name
        kind = 1 if self.homogeneous else 0 if k.startswith("k=") else 2
        value = int(k[2:]) if kind == 0 else 0
        other = self.algorithm != "cc11es"                         # other algorithms after CC-(1+1)-ES
        reward = (self.config.get("algorithm") or {}).get("reward")
        credit = list(CREDIT_LABELS).index(reward) if reward in CREDIT_LABELS else len(CREDIT_LABELS)
        return (setup_rank(self.setup), self.setup, other, self.algorithm if other else "", credit, kind, value, k,
                self.strict, self.name)

    def keyed_overrides(self) -> set[str]:
        """``key=value`` items that may tell this job from another of the same setup."""
        items = set(self.overrides) | {f"{g}={o}" for g, o in self.choices.items()}
        return {i for i in items if i.split("=", 1)[0].split(".")[0].lstrip("+~") not in NOT_METHOD}

    def arms(self, n_arms: int) -> list[int]:
        k_cfg, env = self.config.get("k") or {}, self.config.get("env") or {}
        arms = k_cfg.get("arms") or list(range(1, int(env.get("n_rovers", n_arms)) + 1))
        return [int(a) for a in arms] if len(arms) == n_arms else list(range(1, n_arms + 1))

    def heldout(self) -> float | None:
        """The median held-out score of the job's final teams (``summary.json``), or None if it has none."""
        value = (_read(self.path / "summary.json", "summary") or {}).get("median_heldout_score")
        return None if value is None else float(value)

    def world(self, trust: bool = False):
        """The job's :class:`~rovermarl.env.World` from its config, or None if it cannot be built. A world plug-in's
        (``env._target_``) only with ``trust``: its module runs code."""
        if not trust and (self.config.get("env") or {}).get("_target_") not in (None, "rovermarl.env.World"):
            return None
        for build in (lambda: World.from_config(OmegaConf.create(self.config), trust),
                      lambda: make_world(self.setup)):
            try:
                return build()
            except PluginError:  # the plug-in's own code failed: its one line, not the paper's world in its place
                raise
            except Exception:  # an odd config only costs the trajectory figures
                pass
        return None


def _read(path: Path, kind: str, notes: list[str] | None = None):
    """``path`` checked as ``kind`` (:mod:`rovermarl.record.safe_read`): a job's summary.json (a dict) or a YAML (a
    dict or list); None if it is missing, of another type or refused (then with one note naming file and field)."""
    read, types = (read_json, dict) if kind == "summary" else (read_yaml, (dict, list))
    try:
        found = read(path, kind=kind) if path.is_file() else None
    except OSError as e:
        if notes is not None:
            notes.append(str(e))
        return None
    return found if isinstance(found, types) else None


def load_run(run_dir: Path, size: RunSize | None = None) -> RunCurve:
    score, probs = read_run_curve(run_dir, size)
    match = re.search(r"(\d+)$", run_dir.name)
    return RunCurve(run_dir, int(match[1]) if match else -1, score, probs)


def _exported_runs(path: Path, seeds: int | None, generations) -> list[RunCurve]:
    """The runs of an exported job dir: exact curves, probs on the grid."""
    e = read_exported(path, seeds, generations)
    probs = [None] * len(e.curves.seeds) if e.probs is None else e.probs.astype(np.float64)
    x = None if e.probs is None else e.grid
    return [RunCurve(path, int(seed), e.curves.full(i), probs[i], x) for i, seed in enumerate(e.curves.seeds)]


def load_job(path: Path, notes: list[str]) -> Job | None:
    """Read one job dir (finished or not, or exported); None, with a note, if it has no readable run or one of its
    files is refused (:mod:`rovermarl.record.schemas`)."""
    bad: list[str] = []
    job = _load_job(path, notes, bad)
    if bad:
        notes.append(f"{bad[0]}; job skipped")
        return None
    return job


def _load_job(path: Path, notes: list[str], bad: list[str]) -> Job | None:
    summary = _read(path / "summary.json", "summary", bad)
    choices = dict((summary or {}).get("choices") or {})
    seeds = len((summary or {}).get("seeds") or []) or None
    if (path / "curves.npz").is_file():
        config = _read(path / "config.yaml", "config", bad) or {}
        if bad:
            return None
        config = config if isinstance(config, dict) else {}
        try:
            runs = _exported_runs(path, seeds, config.get("generations"))
        except OSError as e:
            notes.append(f"{e}; job skipped")
            return None
        return Job(path, choices, config, [], runs, True)
    hydra_dir = path / ".hydra"
    if not choices:
        runtime = ((_read(hydra_dir / "hydra.yaml", "hydra", bad) or {}).get("hydra") or {}).get("runtime") or {}
        choices = {g: o for g, o in (runtime.get("choices") or {}).items() if "/" not in g and o is not None}
    overrides = [str(o).replace("'", "").replace('"', "")
                 for o in _read(hydra_dir / "overrides.yaml", "overrides", bad) or []]
    config = (_read(hydra_dir / "config.yaml", "config", bad) if (hydra_dir / "config.yaml").is_file() else
              _read(path / "config.yaml", "config", bad)) or {}                      # CLI, or library use
    if bad:
        return None
    config = config if isinstance(config, dict) else {}
    size = RunSize.of(config)
    runs = []
    for run_dir in sorted((path / "runs").glob("seed_*")):
        if not RUN_DIR.fullmatch(run_dir.name) or not (run_dir / "curve.npz").is_file():   # seed_XXX.<hash>: set aside
            continue
        try:
            runs.append(load_run(run_dir, size))
        except OSError as e:    # safe_read: corrupt, too large, odd; skips that run only
            notes.append(f"{e}; run skipped")
        except Exception as e:  # a half-written or corrupt file skips that run only
            notes.append(f"{run_dir}: unreadable curve.npz ({type(e).__name__}); run skipped")
    if not runs:
        notes.append(f"{path.name}: no finished run yet; job skipped")
        return None
    job = Job(path, choices, config, overrides, runs, summary is not None)
    expected = seeds or config.get("seeds")
    if not job.finished or (expected and len(runs) < expected):
        state = "finished" if job.finished else "unfinished"
        notes.append(f"{path.name}: {state}; plotting the {len(runs)} of {expected or '?'} runs present")
    return job


def check_dir(path: Path) -> Path:
    """``path`` if it is a non-empty directory holding only directories and regular files, else :class:`SweepError`
    (one line)."""
    path = Path(path)
    if not path.exists():
        raise SweepError(f"no such directory: {path}")
    if not path.is_dir():
        raise SweepError(f"not a directory: {path}")
    if not any(path.iterdir()):
        raise SweepError(f"empty directory: {path}")
    try:
        check_tree(path)
    except OSError as e:
        raise SweepError(str(e)) from None
    return path


def find_jobs(path: Path, only: Sequence[Path] | None = None) -> tuple[list[Job], list[str]]:
    """All job dirs under ``path`` (a sweep dir or one job dir), sorted by setup then method; plus notes. ``only``:
    just these job dirs (a relaunch's own). A link, FIFO or device anywhere under ``path`` is refused first."""
    path = check_dir(path)
    dirs = {p.parent for p in path.rglob("summary.json")}
    dirs |= {p.parent.parent.parent for p in path.rglob("runs/seed_*/curve.npz")}
    if only is not None:
        dirs = {d for d in dirs if d.resolve() in {Path(o).resolve() for o in only}}
    if not dirs:
        raise SweepError(f"no job under {path} (no summary.json, runs/seed_*/curve.npz or exported curves.npz)")
    notes: list[str] = []
    jobs = [job for d in sorted(dirs) if (job := load_job(d, notes)) is not None]
    if not jobs:
        raise SweepError(f"no readable run under {path}: {notes[0]}" if notes else
                         f"no readable run under {path} ({len(dirs)} job dirs, none with a runs/seed_*/curve.npz)")
    return sorted(jobs, key=Job.sort_key), notes


def labels(jobs: Sequence[Job]) -> list[str]:
    """Unique method labels: ``k=1``, ``homogeneous``, ``adaptive``; `` strict`` when soft and strict are mixed,
    then the distinguishing overrides (or the job dir) when two jobs would still share a label."""
    mixed = len({j.strict for j in jobs}) > 1
    out = [j.base_label + (" strict" if mixed and j.strict else "") for j in jobs]
    for label in set(out):
        same = [i for i, lab in enumerate(out) if lab == label]
        if len(same) > 1:
            keyed = [jobs[i].keyed_overrides() for i in same]
            common = set.intersection(*keyed)
            for i, items in zip(same, keyed, strict=True):
                extra = sorted(items - common - {f"selection={'strict' if jobs[i].strict else 'soft'}"})
                out[i] = f"{label} ({', '.join(extra)})" if extra else label
    if len(set(out)) < len(out):
        out = [f"{lab} [{j.name}]" if out.count(lab) > 1 else lab for lab, j in zip(out, jobs, strict=True)]
    return out


def soft_strict_pairs(jobs: Sequence[Job]) -> list[tuple[Job, Job]]:
    """(soft, strict) jobs that differ only in selection."""
    def key(job: Job) -> frozenset:
        return frozenset(i for i in job.keyed_overrides() if not i.startswith("selection"))
    soft = {key(j): j for j in jobs if not j.strict}
    return [(soft[key(j)], j) for j in jobs if j.strict and key(j) in soft]


def fig6_job(jobs: Sequence[Job]) -> Job | None:
    """The job whose run the Fig. 6 data shows (see :func:`rovermarl.analysis.export.export_fig6`): the first soft
    duo k=1 job."""
    return next((j for j in jobs if j.setup == "duo" and j.label == "k=1"), None)
