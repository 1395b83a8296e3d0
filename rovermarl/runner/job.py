"""One Hydra job: run its seeds (serially or on Ray), checkpoint them, write every run's files and the summary.

A relaunch of the same job resumes: finished runs (``run.json`` of the same config) are skipped, unfinished
ones continue from their last good checkpoint, so the results equal those of an uninterrupted job.
"""

from __future__ import annotations

import contextlib
import logging
import time
from functools import partial
from pathlib import Path

import numpy as np
from omegaconf import DictConfig, OmegaConf
from tqdm.auto import tqdm

from rovermarl.jit import compile_seconds
from rovermarl.parallel import run_records
from rovermarl.record import atomic, checkpoint, lock
from rovermarl.record.atomic import atomic_open
from rovermarl.record.checkpoint import RunRecord
from rovermarl.record.outputs import (
    close_launch,
    finished,
    launch_progress,
    load_score,
    outcome,
    run_dir,
    save_run,
    summarize,
    verify,
    write_json,
    write_run_json,
)
from rovermarl.record.provenance import describe, provenance, same_code
from rovermarl.record.rerun_log import write_rrd
from rovermarl.record.safe_read import HASH, RunSize, check_tree, load_npy, read_json, safe_label
from rovermarl.runner import budget
from rovermarl.runner.chunk import Run, advance, heldout_score, parts, to_plain
from rovermarl.runner.identity import config_hash
from rovermarl.runner.validate import series_bytes, validate

log = logging.getLogger("rovermarl")
LONG_JOB_S = 600.0                                                      # a job estimated longer says so at INFO


def run_job(cfg: DictConfig, job_dir: Path, name: str = "job", choices: dict | None = None) -> dict:
    """Run ``cfg.seeds`` independent runs into ``job_dir``; returns the summary (also summary.json). The job dir is
    locked meanwhile (:mod:`rovermarl.record.lock`: another launch on it raises ``Locked``)."""
    validate(cfg)
    check_tree(job_dir, "job dir")                      # a copied results dir: no link followed, no FIFO read
    with lock.hold(job_dir, clean=True):                # clean: temp files a killed launch left
        return _run_job(cfg, Path(job_dir), name, choices)


def all_finished(cfg: DictConfig, job_dir: Path) -> bool:
    """Whether launching ``cfg`` into ``job_dir`` computes nothing: every run finished under this identity (by this
    code, under ``resume=strict``), its files verified, and the job summary current. A relaunch whose jobs are all
    so starts no Ray (``rovermarl.train``)."""
    if not cfg.resume:
        return False
    job_dir, key = Path(job_dir), config_hash(to_plain(cfg))
    seeds = [cfg.seed + i for i in range(cfg.seeds)]
    for seed in seeds:
        out = run_dir(job_dir, seed)
        meta = finished(out, key)
        if meta is None or "heldout_score" not in meta or verify(out, meta) or _no_curve(out, cfg.generations):
            return False
        if cfg.resume == "strict" and not same_code(meta.get("provenance")):
            return False
    return _current_summary(job_dir / "summary.json", seeds, cfg.levels) is not None


def _current_summary(path: Path, seeds: list[int], levels, name: str | None = None) -> dict | None:
    """The job summary at ``path`` if it is of exactly these runs and score levels, with held-out scores, else None;
    with ``name``, one that cannot be read is logged (it is then rebuilt from the runs)."""
    try:
        summary = read_json(path, kind="summary")
    except OSError as e:
        if name is not None:
            log.warning("%s: %s is unreadable (%s); rebuilding it from the runs", name, path, type(e).__name__)
        return None
    current = (isinstance(summary, dict) and "heldout_score" in summary and summary.get("seeds") == seeds
               and set(summary.get("first_generation_reaching", ())) == {str(lv) for lv in levels})
    return summary if current else None


def _run_job(cfg: DictConfig, job_dir: Path, name: str, choices: dict | None) -> dict:
    job, job_dir = to_plain(cfg), Path(job_dir)
    key, built = config_hash(job), parts(job)
    algorithm, fresh = built.algorithm, built.evaluation["fresh_ic"]
    series, per_generation = algorithm.series, algorithm.evaluations_per_generation(fresh)
    est = budget.estimate(job, series_bytes(series), per_generation)
    if est.job_s > LONG_JOB_S:
        log.info("%s: estimated about %s on %d CPUs (%s of memory)", name, budget.duration(est.job_s), est.cpus,
                 budget.size(est.total_memory))
    seeds = [cfg.seed + i for i in range(cfg.seeds)]
    outcomes, heldout, cpu, todo, other_code = {}, {}, {}, [], []
    for seed in seeds:
        out = run_dir(job_dir, seed)
        if cfg.resume:
            _set_aside_other_identity(out, key, name)
        meta = finished(out, key) if cfg.resume else None
        if meta is not None and (problem := verify(out, meta) or _no_curve(out, cfg.generations)):
            log.warning("%s: seed %d: %s; recomputing the run", name, seed, problem)
            atomic.remove(out / "run.json")
            meta = None
        if meta is not None and not same_code(meta.get("provenance")):
            other_code.append(meta.get("provenance"))
            meta = None if cfg.resume == "strict" else meta
        if meta is not None:
            outcomes[seed] = outcome(load_score(out, cfg.generations), cfg.levels)
            heldout[seed] = meta["heldout_score"] if "heldout_score" in meta else _backfill(out, meta, built, seed)
            cpu[seed] = meta.get("cpu_s")
            continue
        todo.append(seed)
    if other_code:
        log.warning("%s: %d finished run(s) were made by other code (%s; this is %s): %s", name, len(other_code),
                    describe(other_code[0]), describe(provenance()),
                    "recomputed (resume=strict)" if cfg.resume == "strict" else "kept; resume=strict recomputes them")
    if outcomes:
        log.info("%s: %d of %d runs already finished, skipped", name, len(outcomes), len(seeds))
    summary_path = job_dir / "summary.json"
    _saved_generations(job_dir / ".hydra" / "config.yaml", cfg.generations)   # Hydra rewrote it: also when finished
    if not todo and summary_path.exists() and (summary := _current_summary(summary_path, seeds, cfg.levels, name)):
        return summary                                                     # else stale: rebuilt below

    if not (job_dir / ".hydra" / "config.yaml").exists():              # library use: keep the config beside the runs
        with atomic_open(job_dir / "config.yaml", "w") as f:
            f.write(OmegaConf.to_yaml(job))

    def rrd(path: Path, result: dict) -> None:                          # a run's recording, under record.rerun
        write_rrd(path, result, built.world, series=series, every=cfg.record.every, steps=cfg.record.steps,
                  recording_id=f"seed_{result['seed']:03d}")
    every = max(cfg.checkpoint.every, 1)
    batch = budget.batch_size(job, series_bytes(series))
    if batch < len(todo):
        log.info("%s: %d runs stream in batches of %d (what fits in memory)", name, len(todo), batch)
    close_launch(job_dir)                                               # the compute of a launch that was killed
    t0, evaluations, started, compiling = time.perf_counter(), 0, time.time(), compile_seconds()
    with tqdm(total=len(todo) * cfg.generations, desc=name, unit="gen", disable=None, leave=False,
              dynamic_ncols=True) as bar:
        def on_chunk(rec: RunRecord, advanced: int) -> None:
            bar.update(advanced)
            out = run_dir(job_dir, rec.seed)
            saving = rec.generation // every > (rec.generation - advanced) // every
            if rec.done or saving:                                     # the compute so far, before any file of it
                launch_progress(job_dir, {"started_at": started, "wall_time_s": time.perf_counter() - t0,
                                          "team_evals": evaluations + sum(r.evaluations for r in records),
                                          "runs_advanced": len(todo)})
            if rec.done:
                save_run(job_dir, {**rec.result(), "cpu_s": rec.cpu_s}, series, key, rrd if cfg.record.rerun else None)
                cpu[rec.seed] = rec.cpu_s
                checkpoint.remove(out / "checkpoint.bin")
                outcomes[rec.seed] = outcome(rec.score, cfg.levels)
                heldout[rec.seed] = float(rec.extra["heldout_score"])
                bar.set_postfix_str(f"runs {len(outcomes)}/{len(seeds)}")
            elif saving:
                rec.save(out / "checkpoint.bin", key)

        for i in range(0, len(todo), batch):                            # the records of one batch at a time
            records = [_record(cfg, job_dir, seed, key, series, name) for seed in todo[i:i + batch]]
            bar.update(sum(rec.generation for rec in records))
            run_records(cfg, job, records, on_chunk, advance)
            evaluations += sum(rec.evaluations for rec in records)
    wall = time.perf_counter() - t0
    compiled = compile_seconds() - compiling                           # numba compiling here: not the job's speed
    summary = summarize(choices or {}, seeds, outcomes, list(cfg.levels), wall, team_evals=evaluations,
                        heldout=heldout, compile_s=compiled, cpu_s=cpu)
    summary.update(evals_per_generation=per_generation,                  # what the analysis puts on an x-axis
                   train_ic="fresh" if fresh else "fixed",                # what the learner trained on
                   final_team=algorithm.final_team,                       # which team the held-out score is of
                   agent_steps_per_generation=algorithm.agent_steps_per_generation(fresh),
                   own_agent_steps_per_generation=algorithm.own_agent_steps_per_generation(fresh))
    if cfg.setup.get("coupling_level") is not None:                # the coupling family (conf/setup/coupling*.yaml)
        summary["coupling_level"] = int(cfg.setup.coupling_level)
    write_json(summary_path, summary)
    close_launch(job_dir, {"started_at": started, "finished_at": time.time(), "wall_time_s": wall,
                           "team_evals": summary["team_evals"], "runs_advanced": len(todo)})
    log.info("%s: median final score %.4g over %d seeds, %.1f s (%.0f team evals/s%s)", name,
             summary["median_final_score"], len(seeds), wall, summary["team_evals_per_s"] or 0,
             f", not counting {compiled:.0f} s of numba compiling" if compiled >= 0.05 else "")
    return summary


def _saved_generations(path: Path, generations: int) -> None:
    """Hydra saved the job's config before ``budget.agent_steps`` set its ``generations``: the saved config says the
    generations the job runs (as if given on the command line), so every reader of the job dir sees them."""
    if not path.is_file():
        return
    saved = OmegaConf.load(path)
    if saved.get("generations") != generations:
        saved.generations = generations
        with atomic_open(path, "w") as f:
            f.write(OmegaConf.to_yaml(saved))


def _record(cfg, job_dir: Path, seed: int, key: str, series, name: str) -> RunRecord:
    """Run ``seed``'s record: from its checkpoint when it has a usable one, else fresh."""
    out = run_dir(job_dir, seed)
    problems: list[str] = []
    rec = (checkpoint.resume(out / "checkpoint.bin", key, problems.append, cfg.generations, series,
                             partial(_template, cfg, seed)) if cfg.resume else None)
    if rec is not None and rec.seed != seed:
        problems.append(f"{out / 'checkpoint.bin'} holds seed {rec.seed}, not {seed}; ignoring it")
        rec = None
    if problems:                                                        # one line, whatever went wrong
        log.warning("%s: %s; seed %d %s", name, "; ".join(problems), seed,
                    "starts from scratch" if rec is None else f"resumes at generation {rec.generation}")
    elif rec is not None:
        log.info("%s: seed %d resumes at generation %d", name, seed, rec.generation)
    return rec or RunRecord(seed, cfg.generations, series)


def _template(cfg, seed: int) -> dict:
    """A fresh run ``seed``'s state (:meth:`Run.state <rovermarl.runner.chunk.Run.state>`), initial conditions and
    first events: what a checkpoint must match, key for key, shape for shape, before any of it reaches the kernel."""
    run = Run(to_plain(cfg), seed)
    out = {"state": run.state(), "ic_xy": run.ic[0], "ic_heading": run.ic[1],
           "events": {f"{f}_{k}": v for f, arrays in run.observer.drain().items() for k, v in arrays.items()}}
    if run.ic[2].shape[-1]:
        out["ic_layout"] = run.ic[2]
    return out


def _no_curve(out: Path, generations: int) -> str | None:
    """What is wrong with a finished run's score curve (unreadable, not of ``generations``, or not a finite number),
    else None."""
    try:
        score = load_score(out, generations)
    except Exception as e:  # noqa: BLE001 - any unreadable curve is recomputed
        return f"{out / 'curve.npz'} cannot be read ({type(e).__name__})"
    return None if np.isfinite(score).all() else f"{out / 'curve.npz'} holds non-finite scores"


def _set_aside_other_identity(out: Path, key: str, name: str) -> None:
    """A run dir made under another identity (another config, or other recording switches) moves to
    ``seed_XXX.<its hash>``, so the run starts afresh beside it and the two never mix."""
    other = None
    with contextlib.suppress(OSError, AttributeError):
        other = read_json(out / "run.json").get("config_hash")
    for path in (out / "checkpoint.bin", checkpoint.previous(out / "checkpoint.bin")):
        other = other or (checkpoint.identity(path) if path.exists() else None)
    if not other or other == key:
        return
    other = safe_label(other, f"{name}: {out.name}'s config hash", log.warning, HASH)   # a path part: checked
    aside = out.with_name(f"{out.name}.{other[:12]}")
    n = 1
    while aside.exists():
        aside, n = out.with_name(f"{out.name}.{other[:12]}.{n}"), n + 1
    atomic.replace(out, aside)
    log.warning("%s: %s was made under another identity (config hash %s): moved to %s; the run starts afresh",
                name, out.name, other[:12], aside.name)


def _backfill(out: Path, meta: dict, built, seed: int) -> float:
    """The held-out score of a run finished before runs recorded one, from its final team; added to its run.json."""
    score = heldout_score(built, seed, load_npy(out / "genomes.npy", RunSize.of(None, built.world).genomes()))
    write_run_json(out, {**meta, "heldout_score": score})
    return score
