"""Result files of a job, written atomically beneath the job dir (:mod:`rovermarl.record.atomic`); docs/GUIDE.md
("Outputs") describes each. A job dir holds ``summary.json`` and, per run, ``runs/seed_XXX/``:

    curve.npz               score (G+1,), then the algorithm's declared series (G, ...)
    genomes.npy             final team genomes (N, P)
    initial_conditions.npz  xy (E, N, 2), heading (E, N), [layout (E, K) of a world plug-in]
    behaviour.npz           generation (C,), score (C,), xy (C, E, T+1, N, 2) float32
    occupancy.npz           generation (M,), count (M, E, P) int8
    run.rrd                 Rerun recording (rovermarl.record.rerun_log)
    run.json                written last: the run is finished; checksummed, with each file's size and SHA-256
                            (a relaunch recomputes a run whose files do not verify)
    checkpoint.bin          while the run is unfinished (rovermarl.record.checkpoint)
"""

from __future__ import annotations

import hashlib
import json
import logging
import shutil
from pathlib import Path

import numpy as np

from rovermarl.record.atomic import atomic_open, remove
from rovermarl.record.events import FILES as EVENT_FILES
from rovermarl.record.provenance import provenance
from rovermarl.record.safe_read import RunSize, load_npz, open_regular, read_json

log = logging.getLogger("rovermarl")


def run_dir(job_dir: Path, seed: int) -> Path:
    return Path(job_dir) / "runs" / f"seed_{seed:03d}"


def save_run(job_dir: Path, result: dict, series=(), config_hash: str = "", write_rrd=None) -> Path:
    """Write one finished run's files, ``run.json`` last: ``curve.npz`` holds ``score`` and the declared ``series``
    (:class:`~rovermarl.algorithms.base.Series`); ``write_rrd(path, result)`` adds the recording."""
    out = run_dir(job_dir, result["seed"])
    remove(out / "run.json")                                          # not finished until every file is rewritten
    _savez(out / "curve.npz", {"score": result["score"], **{s.name: result[s.name] for s in series}})
    with atomic_open(out / "genomes.npy") as f:
        np.save(f, result["genomes"])
    ic = {"xy": result["ic_xy"], "heading": result["ic_heading"]}
    if "ic_layout" in result:                                       # a world plug-in's layout (E, K), K > 0
        ic["layout"] = result["ic_layout"]
    _savez(out / "initial_conditions.npz", ic)
    for file in EVENT_FILES:             # the observer's: key "<file>_<name>" -> <file>.npz[name]
        prefix = file + "_"
        _savez(out / f"{file}.npz", {k[len(prefix):]: v for k, v in result.items() if k.startswith(prefix)})
    if write_rrd is not None:
        write_rrd(out / "run.rrd", result)
    names = ["curve.npz", "genomes.npy", "initial_conditions.npz", *(f"{f}.npz" for f in EVENT_FILES)]
    names += ["run.rrd"] if write_rrd is not None else []
    write_run_json(out, {"seed": int(result["seed"]), "generations": len(result["score"]) - 1,
                         "final_score": float(result["score"][-1]),
                         "heldout_score": float(result["heldout_score"]), "config_hash": config_hash,
                         "cpu_s": float(result["cpu_s"]) if "cpu_s" in result else None,
                         "files": {name: digest(out / name) for name in names}, "provenance": provenance()})
    return out


def write_run_json(out: Path, meta: dict) -> None:
    """``run.json`` with its own checksum (``"checksum"``: SHA-256 of the rest, canonical JSON)."""
    meta = {key: value for key, value in meta.items() if key != "checksum"}
    write_json(Path(out) / "run.json", {**meta, "checksum": _checksum(meta)})


def _checksum(meta: dict) -> str:
    return hashlib.sha256(json.dumps(meta, sort_keys=True, separators=(",", ":")).encode()).hexdigest()


def digest(path: Path) -> dict:
    """``{"bytes": size, "sha256": hex}`` of a file."""
    h = hashlib.sha256()
    with open_regular(path) as f:                                     # never a link or a FIFO
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return {"bytes": Path(path).stat().st_size, "sha256": h.hexdigest()}


def verify(out: Path, meta: dict) -> str | None:
    """None if ``run.json`` (``meta``) verifies against its own checksum and every file it lists (``meta["files"]``)
    is there with its size and checksum, else what is wrong, naming the file."""
    run_json = Path(out) / "run.json"
    if meta.get("checksum") != _checksum({k: v for k, v in meta.items() if k != "checksum"}):
        return f"{run_json} does not match its own checksum"
    if not isinstance(meta.get("files"), dict) or "curve.npz" not in meta["files"]:
        return f"{run_json} lists no files to check"
    for name, want in meta["files"].items():
        if not isinstance(want, dict) or Path(name).name != name:
            return f"{run_json} lists {name!r} wrongly"
        path = Path(out) / name
        if not path.is_file():
            return f"{path} is missing"
        if path.stat().st_size != want.get("bytes"):
            return f"{path} has {path.stat().st_size} bytes, run.json says {want.get('bytes')}"
        if digest(path)["sha256"] != want.get("sha256"):
            return f"{path} does not match its checksum in run.json"
    return None


def finished(out: Path, config_hash: str) -> dict | None:
    """The ``run.json`` of ``out`` if it holds a finished run of the config with this hash, else None."""
    try:
        meta = read_json(Path(out) / "run.json")
    except OSError:
        return None
    return meta if isinstance(meta, dict) and meta.get("config_hash") == config_hash else None


def load_score(out: Path, generations: int | None = None) -> np.ndarray:
    """The score (G+1,) of a run's curve.npz, its members checked against ``generations`` before they are read."""
    return load_npz(Path(out) / "curve.npz", RunSize(generations).curve(), ("score",), stored=True)["score"]


def _savez(path: Path, arrays: dict) -> None:
    with atomic_open(path) as f:
        np.savez(f, **arrays)


def first_reaching(score: np.ndarray, level: float) -> int | None:
    """First generation g with score[g] >= level (score[0] is the initial team), or None."""
    hits = np.flatnonzero(score >= level)
    return int(hits[0]) if hits.size else None


def outcome(score: np.ndarray, levels) -> dict:
    """What the summary keeps of one run's score curve (G+1,): its final score and first generation reaching each
    level (the driver then drops the curve)."""
    return {"final": float(score[-1]), "first": {str(lv): first_reaching(score, lv) for lv in levels}}


def summarize(choices: dict, seeds: list[int], outcomes: dict[int, dict], levels, wall_time_s: float,
              team_evals: int, heldout: dict[int, float], compile_s: float = 0.0,
              cpu_s: dict[int, float | None] | None = None) -> dict:
    """The job's summary of ``outcomes`` (:func:`outcome` per seed), held-out scores and CPU-seconds (None: not
    recorded); the rate of team evaluations leaves out ``compile_s``, the wall time numba spent compiling here."""
    final = {str(s): outcomes[s]["final"] for s in seeds}
    held = {str(s): float(heldout[s]) for s in seeds}
    return {
        "choices": choices,
        "seeds": list(seeds),
        "final_score": final,
        "median_final_score": float(np.median(list(final.values()))),
        "heldout_score": held,
        "median_heldout_score": float(np.median(list(held.values()))),
        "first_generation_reaching": {
            str(lv): {str(s): outcomes[s]["first"][str(lv)] for s in seeds} for lv in levels},
        "wall_time_s": wall_time_s,
        "team_evals": team_evals,
        "compile_s": compile_s,
        "team_evals_per_s": team_evals / (wall_time_s - compile_s) if wall_time_s > compile_s else None,
        "cpu_s": {str(s): (None if (cpu_s or {}).get(s) is None else float(cpu_s[s])) for s in seeds},
        "provenance": provenance(),
    }


def write_json(path: Path, obj: dict) -> None:
    with atomic_open(path, "w") as f:
        json.dump(obj, f, indent=2)
        f.write("\n")


INVOCATIONS, LAUNCH = "invocations.jsonl", "launch.json"   # every launch's compute; the running launch's so far


def launch_progress(job_dir: Path, record: dict) -> None:
    """The running launch's compute so far (``wall_time_s``, ``team_evals``, ``runs_advanced``) into the job's
    ``launch.json``, replaced atomically: what a launch that is killed leaves behind."""
    write_json(Path(job_dir) / LAUNCH, record)


def close_launch(job_dir: Path, record: dict | None = None) -> None:
    """Append a launch's compute to the job's ``invocations.jsonl``: ``record`` (a launch that finished), or else
    the ``launch.json`` that a killed launch left (marked ``"interrupted": true``); then remove ``launch.json``."""
    job_dir = Path(job_dir)
    progress = job_dir / LAUNCH
    if record is None:
        if not progress.is_file():
            return
        try:
            record = {**read_json(progress), "interrupted": True}
            float(record["wall_time_s"]), int(record["team_evals"])
        except (OSError, ValueError, TypeError, KeyError) as e:
            log.warning("%s is unreadable (%s): the compute of the launch that left it is not counted",
                        progress, type(e).__name__)
            remove(progress)
            return
    log_path = job_dir / INVOCATIONS
    with atomic_open(log_path) as f:                                   # rewritten whole: never a partial line
        if log_path.is_file():
            with open_regular(log_path) as old:                        # copied in chunks, however long
                shutil.copyfileobj(old, f, 1 << 20)
        f.write((json.dumps(record) + "\n").encode())
    remove(progress)
