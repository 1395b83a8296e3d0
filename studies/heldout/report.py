"""Held-out scores and final teams for compact results committed before those features (issues 33 and 43): a one-off
migration, done for every committed results dir; kept for results made by an older rovermarl.

``launchers/heldout.sh`` recomputes each job's runs (a run is a pure function of its config and seed) into a sweep
dir; ``python studies/heldout/report.py merge SWEEP_DIR RESULTS_DIR`` (:func:`merge`) then adds each run's held-out
score and final team to the committed job, once every recomputed run ends at the committed final score, bit for bit:
the curves do not change. ``python studies/heldout/report.py done JOB_DIR`` exits 0 if the job's summary has
held-out scores, 3 if not (or if it is refused: it is recomputed); any other status is a failure of its own.
``python studies/heldout/report.py overrides JOB_DIR`` prints the overrides that recompute the job, one a line
(:func:`overrides_of`: read from its files and allow-listed, never from its dir name).
"""

from __future__ import annotations

import re
import sys
from pathlib import Path

import numpy as np
from omegaconf import OmegaConf

from rovermarl.analysis.cli import Parser, fail, one_line_errors, say
from rovermarl.analysis.export import final_teams
from rovermarl.analysis.results import ResultsError
from rovermarl.analysis.sweep import RunCurve
from rovermarl.config import compose_jobs, quote_numeric_options
from rovermarl.errors import ConfigError
from rovermarl.record.atomic import beneath
from rovermarl.record.outputs import atomic_open, write_json
from rovermarl.record.safe_read import check_tree, read_json, read_yaml, safe_label
from rovermarl.resources import CONF_DIR, group_names, packaged
from rovermarl.runner.identity import NOT_IN_DIR_NAMES, RUNTIME

PROG = "studies/heldout/report.py"
NOT_DONE = 3                    # done's "no held-out scores": apart from a crash's 1, which heldout.sh must not skip


def done(job: Path) -> bool:
    """Whether the job dir ``job``'s summary.json has held-out scores (False if it is refused: it is recomputed)."""
    try:
        return bool(read_json(Path(job) / "summary.json", kind="summary").get("heldout_score"))
    except (OSError, AttributeError):
        return False


def merge(sweep: Path, results: Path, log=print) -> list[str]:
    """Add the held-out scores and final teams of ``sweep``'s finished jobs to the same-named jobs of ``results``;
    returns the names of the jobs updated. A job whose recomputed final scores differ from the committed ones is
    refused (an error naming it and the first seed that differs), and nothing of it is written."""
    updated = []
    check_tree(results)                                 # a linked job dir would have its summary written elsewhere
    check_tree(sweep)
    for path in sorted(Path(results).glob("*/summary.json")):
        name = path.parent.name
        done = Path(sweep) / name / "summary.json"
        if not done.is_file():
            continue
        try:
            committed, recomputed = read_json(path, kind="summary"), read_json(done, kind="summary")
        except OSError as e:                            # refused (safe_read): one line, the other jobs go on
            log(f"{e}; skipped")
            continue
        want, got = committed.get("final_score") or {}, recomputed.get("final_score") or {}
        held = recomputed.get("heldout_score") or {}
        if not want or set(got) != set(want) or set(held) != set(want):
            log(f"{name}: {len(got)} of {len(want)} runs recomputed: skipped")
            continue
        for seed, value in want.items():
            if got[seed] != value:
                raise ResultsError(f"{name}: seed {seed} ends at {got[seed]} recomputed, {value} committed: "
                                   "not the same run; its held-out score is not added")
        runs = [RunCurve(Path(sweep) / name / "runs" / f"seed_{int(s):03d}", int(s), np.empty(0), None)
                for s in sorted(want, key=int)]
        teams = final_teams(runs)
        added = []
        if teams is not None and not (path.parent / "genomes.npz").is_file():
            with atomic_open(path.parent / "genomes.npz") as f:
                np.savez_compressed(f, **teams)
            added.append(f"final teams of {len(runs)} runs")
        if committed.get("heldout_score") != held:
            committed["heldout_score"] = held
            committed["median_heldout_score"] = float(np.median([held[s] for s in sorted(held, key=int)]))
            write_json(path, committed)
            added.append(f"held-out median {committed['median_heldout_score']:.4g} over {len(held)} runs")
        if added:
            updated.append(name)
            log(f"{name}: " + " and ".join(added) + " added")
    return updated


# ---- a job's overrides, read back from its files ---------------------------------------------------------------
_KEY = re.compile(r"[A-Za-z_]\w*(?:\.[A-Za-z_]\w*)*")
_OVERRIDE = re.compile(rf"(?P<key>{_KEY.pattern})=(?P<value>'?[\w.\-]{{1,100}}'?|\[[\w.\-, ]{{0,400}}\])")
_PLAIN = (bool, int, float, str)


def overrides_of(job_dir: Path) -> list[str]:
    """The overrides that recompute the job of ``job_dir``, each one allow-listed (:func:`allowed`): its
    ``.hydra/overrides.yaml`` (a job the CLI ran), else what its committed ``config.yaml`` and ``summary.json``
    (``choices``) hold that the packaged defaults do not (compact results). Files are read through
    :mod:`rovermarl.record.safe_read`, the dir's name never; one-line ConfigError or ``OSError`` for anything else."""
    job_dir = Path(job_dir)
    if safe_label(job_dir.name, "job dir") != job_dir.name or not job_dir.is_dir():
        raise ConfigError("job dir", job_dir.name, "must be a directory whose name is letters, digits, _.,=+-")
    check_tree(job_dir, "job dir")
    overrides_file = job_dir / ".hydra" / "overrides.yaml"
    if overrides_file.is_file():
        given = [str(o) for o in read_yaml(overrides_file, kind="overrides")]
        base = _base([o for o in given if o.partition("=")[0] in group_names() and allowed(o, {}, str(overrides_file))])
        return [o for o in given if allowed(o, base, str(overrides_file))]
    source = str(job_dir / "config.yaml")
    config = read_yaml(job_dir / "config.yaml", kind="config")      # its interpolations plain references (schemas)
    config = _plain(OmegaConf.create(config)) if isinstance(config, dict) else {}
    choices = (read_json(job_dir / "summary.json", kind="summary") or {}).get("choices") or {}
    picked = [f"{g}={o}" for g, o in sorted(choices.items())
              if g not in RUNTIME and o is not None and (g, o) not in _default_choices()]
    base = _base(picked)
    out = [*picked, *_differences(config, base, "", source)]
    if (config.get("budget") or {}).get("agent_steps") is not None:        # generations follow from the budget
        out = [o for o in out if not o.startswith("generations=")]
    return [o for o in quote_numeric_options(out) if allowed(o, base, source)]


def allowed(override: str, base: dict, source: str) -> bool:
    """Whether ``override`` recomputes the job: True for ``key=value`` with a plain value (a word, a number or a list
    of them: no ``+``, ``~``, quotes inside or interpolation) whose key is a config group (the value one of its
    options) or a key of ``base`` (the packaged config of the job's options); False for a runtime setting or ``seeds``
    (the launcher chooses those); else ConfigError naming it and ``source``."""
    key = override.partition("=")[0]
    if _KEY.fullmatch(key) and key.split(".")[0] in NOT_IN_DIR_NAMES:
        return False
    m = _OVERRIDE.fullmatch(override)
    if m is None:
        raise ConfigError("override", override, "is not a plain KEY=VALUE (no +, ~, interpolation or function), "
                          "in " + source)
    option = m["value"].strip("'")
    if m["key"] in group_names():
        if not (CONF_DIR / m["key"] / f"{option}.yaml").is_file():
            raise ConfigError(m["key"], option, f"is not an option of the packaged group, in {source}")
        return True
    node = base
    for part in m["key"].split("."):
        if not isinstance(node, dict) or part not in node:
            raise ConfigError(m["key"], m["value"], f"is not a key of the packaged config, in {source}")
        node = node[part]
    return True


def _default_choices() -> set[tuple[str, str]]:
    """(group, option) of the packaged config's defaults list."""
    return {(g, str(o)) for item in packaged("config.yaml").get("defaults", []) if isinstance(item, dict)
            for g, o in item.items()}


def _differences(config, base, path: str, source: str) -> list[str]:
    """``key=value`` for each plain value of ``config`` that differs from ``base`` (the packaged config of its
    choices); ConfigError for a key ``base`` lacks or a list or node that differs in another way."""
    out = []
    for key, value in config.items():
        name = f"{path}{key}"
        if key == "_target_" or (not path and key in NOT_IN_DIR_NAMES) or base.get(key) == value:
            continue
        if key not in base:
            raise ConfigError(name, "...", f"is not a key of the packaged config, in {source}")
        if isinstance(value, dict) and isinstance(base[key], dict):
            out += _differences(value, base[key], f"{name}.", source)
        elif isinstance(value, _PLAIN) or (isinstance(value, list) and all(isinstance(v, _PLAIN) for v in value)):
            out.append(f"{name}=" + (f"[{','.join(map(str, value))}]" if isinstance(value, list) else str(value)))
        else:
            raise ConfigError(name, type(value).__name__, f"differs from the packaged config, in {source}")
    return out


def _base(picked: list[str]) -> dict:
    """The packaged config of the options ``picked`` (plain, resolved); composition errors in one line."""
    return _plain(compose_jobs(quote_numeric_options(picked), multirun=False)[0])


def _plain(cfg) -> dict:
    return OmegaConf.to_container(cfg, resolve=True)


def main(argv=None) -> None:
    p = Parser(prog=PROG, description="Add recomputed runs' held-out scores to committed compact results.")
    p.add_argument("action", choices=("merge", "done", "overrides"))
    p.add_argument("paths", type=Path, nargs="+", help="merge: SWEEP_DIR (of launchers/heldout.sh, e.g. "
                   "outputs/heldout/paper) RESULTS_DIR (e.g. results/paper); done: JOB_DIR (exit 0 if its summary "
                   "has held-out scores, 3 if not); overrides: JOB_DIR (the overrides that recompute it, one a line)")
    args = p.parse_args(argv)
    n = 2 if args.action == "merge" else 1
    if len(args.paths) != n:
        fail(PROG, f"{args.action} takes {n} path(s)")
    with one_line_errors(PROG):
        if args.action == "merge":
            with beneath(args.paths[1], create=False):                  # a job dir swapped for a link: refused
                merge(args.paths[0], args.paths[1], log=say(PROG))
        elif args.action == "overrides":
            print("\n".join(overrides_of(args.paths[0])))
        elif not done(args.paths[0]):
            sys.exit(NOT_DONE)


if __name__ == "__main__":
    main()
