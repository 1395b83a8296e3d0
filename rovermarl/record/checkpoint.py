"""The driver's record of each run, and its checkpoint files.

A run advances in chunks (on Ray or in this process). Each chunk returns its slice of the history, its events and the
run's compact state; :class:`RunRecord` stitches them together. Every ``checkpoint.every`` generations the record is
written to ``runs/seed_XXX/checkpoint.bin`` (the previous one kept as ``checkpoint.prev.bin``): one header line
``RMCKPT2 <sha256 of payload>``, then an ``.npz`` payload; a truncated or corrupt file fails the checksum.
"""

from __future__ import annotations

import hashlib
import io
import json
import math
from pathlib import Path

import numpy as np

from rovermarl.record import atomic
from rovermarl.record.safe_read import ANY, FREE, Spec, load_npz_bytes, read_bytes

MAGIC = b"RMCKPT2"


class CheckpointError(Exception):
    """A checkpoint file that cannot be used (message names the file and what is wrong)."""


class RunRecord:
    """Everything the driver knows of one run: its score and the algorithm's declared ``series`` (full length), the
    observer's events so far (per result file), the run's extras and the state to resume from."""

    def __init__(self, seed: int, generations: int, series=()):
        self.seed, self.generations = int(seed), int(generations)
        self.generation = 0
        self.state: dict | None = None
        self.score = np.full(generations + 1, np.nan)
        self.history: dict[str, np.ndarray] = {s.name: s.empty(generations) for s in series}
        self.events: dict[str, list[np.ndarray]] = {}                 # "<file>_<key>" -> parts
        self.extra: dict[str, np.ndarray] = {}          # ic_xy, ic_heading, [ic_layout], genomes, heldout_score
        self.evaluations = 0                                          # team evaluations in this process's chunks
        self.cpu_s = 0.0                                              # CPU-seconds of every chunk, resumes included

    @property
    def done(self) -> bool:
        return self.generation >= self.generations

    def add(self, chunk: dict) -> int:
        """Apply one chunk returned by :func:`rovermarl.runner.chunk.advance`; returns generations advanced."""
        start, stop = chunk["start"], chunk["stop"]
        if start != self.generation:
            raise RuntimeError(f"seed {self.seed}: chunk starts at {start}, record is at {self.generation}")
        if "initial_score" in chunk:
            self.score[0] = chunk["initial_score"]
        self.score[start + 1:stop + 1] = chunk["score"]
        for name, values in chunk["series"].items():
            self.history[name][start:stop] = values
        for file, arrays in chunk["events"].items():
            for key, values in arrays.items():
                self.events.setdefault(f"{file}_{key}", []).append(values)
        for key in ("ic_xy", "ic_heading", "ic_layout", "genomes", "heldout_score"):
            if key in chunk:
                self.extra[key] = chunk[key]
        self.state, self.generation = chunk["state"], stop
        self.evaluations += chunk["evaluations"]
        self.cpu_s += float(chunk.get("cpu_s", 0.0))
        return stop - start

    def result(self) -> dict:
        """The finished run's arrays (what :func:`rovermarl.record.outputs.save_run` writes)."""
        events = {key: np.concatenate(parts) for key, parts in self.events.items()}
        return {"seed": self.seed, "score": self.score, **self.history, **events, **self.extra}

    # ---- checkpoint files -----------------------------------------------------------------------
    def save(self, path: Path, config_hash: str) -> None:
        """Write atomically, the previous checkpoint kept as :func:`previous`; only the generations done are written."""
        g = self.generation
        arrays = {key: value for key, value in self.result().items() if key != "seed"}
        arrays["score"] = self.score[:g + 1]
        arrays.update({key: values[:g] for key, values in self.history.items()})
        meta = {"seed": self.seed, "generations": self.generations, "generation": self.generation,
                "config_hash": config_hash, "history_keys": list(self.history), "event_keys": list(self.events),
                "extra_keys": sorted(self.extra), "cpu_s": self.cpu_s,
                "state": _encode(self.state, arrays)}
        buf = io.BytesIO()
        np.savez(buf, _meta=np.array(json.dumps(meta)), **arrays)
        payload = buf.getvalue()
        with atomic.atomic_open(path, aside=previous(path)) as f:           # complete before touching the old ones
            f.write(MAGIC + b" " + hashlib.sha256(payload).hexdigest().encode() + b"\n" + payload)

    @classmethod
    def load(cls, path: Path, config_hash: str, generations: int | None = None, series=None,
             template=None) -> RunRecord:
        """Read and verify a checkpoint (of a run of ``generations``, if given), else :class:`CheckpointError` naming
        the file. Before anything is allocated its numbers are checked against each other and the config, every
        member must be stored (nothing inflates) and the declared ``series`` (if given) be the only ones; the state
        must match ``template()`` (a fresh run's) key for key in shape, dtype and finite values."""
        path = Path(path)
        try:
            data = read_bytes(path, cap=_cap(generations))
        except OSError as e:
            raise CheckpointError(f"{path}: cannot read ({e.strerror or e})") from None
        header, _, payload = data.partition(b"\n")
        parts = header.split(b" ")
        if len(parts) != 2 or parts[0] != MAGIC:
            raise CheckpointError(f"{path}: not a rovermarl checkpoint (bad header)")
        if hashlib.sha256(payload).hexdigest().encode() != parts[1]:
            raise CheckpointError(f"{path}: checksum mismatch (truncated or corrupt, {len(data)} bytes)")
        try:
            arrays = load_npz_bytes(payload, str(path), _specs(generations, series), ("_meta", "score"))
            meta = json.loads(str(arrays.pop("_meta")))
            if meta["config_hash"] != config_hash:
                raise CheckpointError(f"{path}: written by a different config (hash {str(meta['config_hash'])[:12]}, "
                                      f"expected {config_hash[:12]})")
            _check_sizes(meta, arrays, generations)
            if not set(meta["extra_keys"]) <= EXTRA:
                raise ValueError(f"extra arrays {sorted(set(meta['extra_keys']) - EXTRA)} in an unfinished run")
            if series is not None and meta["history_keys"] != [s.name for s in series]:
                raise ValueError(f"series {meta['history_keys']}, the algorithm declares {[s.name for s in series]}")
            rec = cls(meta["seed"], meta["generations"])
            rec.generation = meta["generation"]
            rec.cpu_s = float(meta.get("cpu_s", 0.0))
            if not 0 <= rec.cpu_s < 1e9:
                raise ValueError(f"cpu_s {rec.cpu_s!r} is not a number of seconds")
            rec.score[:len(arrays["score"])] = arrays["score"]
            rec.history = {key: _full(arrays[key], rec.generations) for key in meta["history_keys"]}
            rec.extra = {key: arrays[key] for key in meta["extra_keys"]}
            rec.events = {key: [arrays[key]] for key in meta["event_keys"]}
            rec.state = _decode(meta["state"], arrays)
            if template is not None:
                _check_form(rec, template(), rec.generation)
        except CheckpointError:
            raise
        except Exception as e:  # noqa: BLE001 - any malformed content is a checkpoint that cannot be used
            raise CheckpointError(f"{path}: malformed content ({type(e).__name__}: "
                                  f"{' '.join(str(e).split())[:120]})") from None
        return rec


EXTRA = frozenset({"ic_xy", "ic_heading", "ic_layout"})         # what an unfinished run's record holds besides


def _cap(generations: int | None) -> int:
    """The most bytes a checkpoint of a run of ``generations`` may have (its series, events and state)."""
    g = generations if isinstance(generations, int) and 0 <= generations <= 10**10 else 10**6
    return (64 << 20) + 4096 * g


def _specs(generations: int | None, series) -> dict:
    """What a checkpoint's members may be: ``_meta`` (a JSON string), ``score`` (g+1,), the declared ``series``
    (g, *shape), and any other array (state, events, initial conditions: checked later by :func:`_check_form`)."""
    g = generations if isinstance(generations, int) and 0 <= generations <= 10**10 else FREE
    specs = {"_meta": Spec((), "U"), "score": Spec((None,), "f", g + 1),
             ANY: tuple(Spec((None,) * n, "biuf", FREE) for n in range(7))}
    for s in series or ():
        specs[s.name] = Spec((None, *s.shape), np.dtype(s.dtype).kind, g)
    return specs


def _check_form(rec: RunRecord, template: dict, done: int) -> None:
    """Raise ValueError unless ``rec``'s state, initial conditions and events have the form of ``template``
    (``{"state", "ic_xy", "ic_heading", ["ic_layout"], "events"}`` of a fresh run of the same config and seed)."""
    arrays: dict = {}
    encoded = _encode(template["state"], arrays)                   # as a checkpoint holds it: plain, arrays apart
    _same(rec.state, _decode(encoded, arrays), "state")
    for key in EXTRA:
        if (key in rec.extra) != (key in template):
            raise ValueError(f"{key} {'missing' if key in template else 'unexpected'}")
        if key in template:
            _same(rec.extra[key], np.asarray(template[key]), key)
    for key, parts in rec.events.items():
        want, got = template["events"].get(key), parts[0]
        if want is None or got.dtype != want.dtype or got.shape[1:] != want.shape[1:] or len(got) > done + 2:
            raise ValueError(f"events {key!r} of shape {got.shape} {got.dtype}, not a fresh run's (first axis at most "
                             f"{done + 2})")


def _kind(value) -> type:
    """The JSON kind of a plain value (a float subclass is a float)."""
    return next((t for t in (bool, int, float, str) if isinstance(value, t)), type(value))


def _same(got, want, where: str) -> None:
    """Raise ValueError unless ``got`` has the form of ``want``: the same keys, lengths, Python types, strings,
    array shapes and dtypes, and finite numbers wherever ``want`` has them."""
    if isinstance(want, dict):
        if not isinstance(got, dict) or set(got) != set(want):
            raise ValueError(f"{where}: keys {sorted(got) if isinstance(got, dict) else type(got).__name__}, "
                             f"not {sorted(want)}")
        for key in want:
            _same(got[key], want[key], f"{where}/{key}")
    elif isinstance(want, list):
        if not isinstance(got, list) or len(got) != len(want):
            raise ValueError(f"{where}: not a list of {len(want)}")
        for i, (g, w) in enumerate(zip(got, want, strict=True)):
            _same(g, w, f"{where}/{i}")
    elif isinstance(want, np.ndarray):
        if not isinstance(got, np.ndarray) or got.shape != want.shape or got.dtype != want.dtype:
            raise ValueError(f"{where}: {getattr(got, 'shape', type(got).__name__)} {getattr(got, 'dtype', '')}, "
                             f"not {want.shape} {want.dtype}")
        if got.dtype.kind == "f" and not (np.isfinite(got) | ~np.isfinite(want)).all():
            raise ValueError(f"{where}: non-finite values")
    elif _kind(got) != _kind(want):
        raise ValueError(f"{where}: a {type(got).__name__}, not a {type(want).__name__}")
    elif isinstance(want, str) and got != want:
        raise ValueError(f"{where}: {got[:40]!r}, not {want!r}")
    elif isinstance(want, float) and math.isfinite(want) and not math.isfinite(got):
        raise ValueError(f"{where}: {got}")


def _check_sizes(meta: dict, arrays: dict, generations: int | None) -> None:
    """Raise ValueError unless the checkpoint's counts agree with each other, its arrays and the config."""
    total, done = meta["generations"], meta["generation"]
    if not all(isinstance(x, int) and not isinstance(x, bool) for x in (meta["seed"], total, done)):
        raise ValueError("seed, generations and generation must be integers")
    if generations is not None and total != generations:
        raise ValueError(f"generations={total}, the config asks for {generations}")
    if not 0 < done <= total or arrays["score"].shape != (done + 1,):
        raise ValueError(f"generation {done} of {total} with {arrays['score'].shape[0]} scores")
    for key in meta["history_keys"]:
        if arrays[key].ndim < 1 or len(arrays[key]) != done:
            raise ValueError(f"series {key!r} holds {len(arrays[key])} generations, not {done}")


def _full(done: np.ndarray, generations: int) -> np.ndarray:
    """A series of the generations done (g, ...) at its full length (generations, ...); the rest is computed later."""
    out = np.zeros((generations, *done.shape[1:]), dtype=done.dtype)
    out[:len(done)] = done
    return out


def identity(path: Path) -> str | None:
    """The config hash a checkpoint file was written under, or None if it cannot be read."""
    try:
        header, _, payload = read_bytes(path, _cap(None)).partition(b"\n")
        meta = load_npz_bytes(payload, str(path), _specs(None, ()), ("_meta",))["_meta"]
        return str(json.loads(str(meta))["config_hash"])
    except Exception:  # noqa: BLE001 - any unreadable file has no identity
        return None


def previous(path: Path) -> Path:
    return Path(path).with_suffix(".prev.bin")


def resume(path: Path, config_hash: str, warn, generations: int | None = None, series=None,
           template=None) -> RunRecord | None:
    """The newest good checkpoint at ``path`` (or its ``.prev``) of a run of ``generations``, or None;
    ``warn(msg)`` explains fallbacks. ``series`` and ``template``: see :meth:`RunRecord.load`."""
    for candidate in (Path(path), previous(path)):
        if not candidate.exists():
            continue
        try:
            return RunRecord.load(candidate, config_hash, generations, series, template)
        except CheckpointError as e:
            warn(f"{e}; ignoring it")
    return None


def remove(path: Path) -> None:
    for p in (Path(path), previous(path)):
        atomic.remove(p)


def _encode(obj, arrays: dict, prefix: str = "state"):
    """JSON-able form of a state: arrays move into ``arrays`` under a path key."""
    if isinstance(obj, np.ndarray):
        arrays[prefix] = obj
        return {"__array__": prefix}
    if isinstance(obj, dict):
        return {str(k): _encode(v, arrays, f"{prefix}/{k}") for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_encode(v, arrays, f"{prefix}/{i}") for i, v in enumerate(obj)]
    if isinstance(obj, np.generic):
        return obj.item()
    return obj


def _decode(obj, arrays: dict):
    if isinstance(obj, dict):
        if set(obj) == {"__array__"}:
            return arrays[obj["__array__"]]
        return {k: _decode(v, arrays) for k, v in obj.items()}
    if isinstance(obj, list):
        return [_decode(v, arrays) for v in obj]
    return obj
