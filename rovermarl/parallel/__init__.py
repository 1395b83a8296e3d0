"""Where a job's independent runs execute: the backend ``parallel._target_`` names (``conf/parallel/*.yaml``),
:class:`Serial` (one after another in this process) or :class:`~rovermarl.parallel.ray_backend.Ray`.

This package only dispatches chunks: the chunk function (:func:`rovermarl.runner.chunk.advance`) is passed in, and
``on_chunk(record, advanced)`` runs here after each chunk. A record (:class:`~rovermarl.record.checkpoint.RunRecord`)
has ``seed``, ``state``, ``done`` and ``add(chunk) -> generations advanced``.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import ClassVar

from rovermarl.errors import ConfigError, build, integer
from rovermarl.parallel.errors import BackendError

__all__ = ["Backend", "BackendError", "Serial", "backend", "run_records"]
OnChunk = Callable[[object, int], None]


@dataclass(frozen=True)
class Backend:
    """A backend: its config's keys are its fields, each checked when it is built (one line naming the key)."""

    chunk: int                          # generations per call: progress and checkpoint granularity
    uses_ray: ClassVar[bool] = False    # whether the launch starts (or joins) Ray for it
    shards: ClassVar[int] = 1           # processes one team evaluation is split over (1: the run's own)

    def __post_init__(self):
        integer("chunk", self.chunk, 1)

    def run(self, cfg, job: dict, records: list, on_chunk: OnChunk, advance: Callable) -> None:
        """Advance every record to its end with ``advance``; ``job`` is the plain config the chunks get."""
        raise NotImplementedError


@dataclass(frozen=True)
class Serial(Backend):
    """The runs one after another in this process, without Ray (for debugging)."""

    def run(self, cfg, job: dict, records: list, on_chunk: OnChunk, advance: Callable) -> None:
        for rec in records:
            while not rec.done:
                on_chunk(rec, rec.add(advance(job, rec.seed, rec.state, self.chunk)))


def backend(node) -> Backend:
    """The backend of a ``parallel`` config node (a mapping with a ``_target_``); one-line ConfigError naming the
    key for an unknown, missing or bad key."""
    from hydra.utils import get_object
    from omegaconf import OmegaConf

    node = OmegaConf.to_container(node, resolve=True) if OmegaConf.is_config(node) else node
    node = dict(node) if isinstance(node, dict) else node              # a copy: its _target_ is taken out
    if not isinstance(node, dict) or not isinstance(node.get("_target_"), str):
        raise ConfigError("parallel", node, "must be a config with a _target_ (pick an option of the group)")
    target = node.pop("_target_")
    try:
        cls = get_object(target)
    except Exception as e:  # noqa: BLE001 - any import problem is the target's
        raise ConfigError("parallel._target_", target, "cannot be imported: " + " ".join(str(e).split())) from None
    if not (isinstance(cls, type) and issubclass(cls, Backend)):
        raise ConfigError("parallel._target_", target, "must name a subclass of rovermarl.parallel.Backend")
    return build("parallel", cls, node)


def run_records(cfg, job: dict, records: list, on_chunk: OnChunk, advance: Callable) -> None:
    """Advance every record to its end with ``advance`` on the backend of ``cfg.parallel``."""
    backend(cfg.parallel).run(cfg, job, records, on_chunk, advance)
