"""Whether a sweep's figures are up to date: a stamp of every file they are drawn from and of the drawing options,
kept in the figures' ``index.json``. Light (no matplotlib), so a relaunch that changed nothing skips the drawing."""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

from rovermarl.record.safe_read import check_tree, read_bytes, read_json

FORMATS = ("png", "pdf")   # the figures' default formats
INPUTS = ("summary.json", "run.json", "curve.npz", "curves.npz", "behaviour.npz", "occupancy.npz", "config.yaml",
          "fig6.npz", "compute.json")


def options(thresholds=None, formats=FORMATS, update_run=None, update_gen=None, xscale="linear", x="auto",
            trust=False) -> dict:
    """The drawing options that a figure set depends on, as :func:`rovermarl.analysis.figures.plot_sweep` takes
    them (its defaults)."""
    return {"thresholds": dict(thresholds or {}), "formats": list(formats), "update_run": update_run,
            "update_gen": update_gen, "xscale": xscale, "x": x, "trust": trust}


def current_index(path: Path, out: Path | None = None, **kwargs) -> dict | None:
    """The figures' index of ``path`` (in ``out``, default ``path/figures``) if it is up to date with its inputs and
    the drawing options ``kwargs`` (:func:`options`), else None: then they must be drawn."""
    out = Path(out) if out is not None else Path(path) / "figures"
    stamp = inputs_stamp(path, out, **options(**kwargs))
    return read_json(out / "index.json") if up_to_date(out, stamp) else None


def inputs_stamp(path: Path, out: Path, **options) -> str:
    """A hash of the figures' input files under ``path`` (names :data:`INPUTS`, not under ``out``: their sizes and
    modification times, a config's content) and of ``options``. A link, FIFO or device under ``path`` is refused
    first (:class:`~rovermarl.record.safe_read.Unsafe`): a FIFO named config.yaml would hang the read."""
    check_tree(path)
    path, out = Path(path), Path(out).resolve()
    h = hashlib.sha256(json.dumps(options, sort_keys=True, default=str).encode())
    for f in sorted(p for name in INPUTS for p in path.rglob(name)):
        if out in f.resolve().parents:
            continue
        st = f.stat()                  # configs by content: Hydra rewrites .hydra/config.yaml at every launch
        key = hashlib.sha256(read_bytes(f)).hexdigest() if f.suffix == ".yaml" else f"{st.st_size}\0{st.st_mtime_ns}"
        h.update(f"{f.relative_to(path)}\0{key}\n".encode())
    return h.hexdigest()


def up_to_date(out: Path, stamp: str) -> bool:
    """Whether ``out/index.json`` was written from inputs with this stamp and every file it lists is still there."""
    try:
        index = read_json(Path(out) / "index.json")
    except OSError:
        return False
    if not isinstance(index, dict):
        return False
    files = [Path(out) / f for fig in index.get("figures", []) for f in fig.get("files", [])]
    return index.get("inputs") == stamp and all(f.exists() for f in files)
