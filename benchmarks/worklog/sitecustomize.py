"""Counts executed chunks for ``benchmarks/soak.py``, outside the package: on ``PYTHONPATH`` with
``ROVERMARL_WORK_LOG`` set, it wraps :func:`rovermarl.runner.chunk.advance` in every process (driver and Ray
workers) so that each finished chunk appends ``seed start stop`` to that file."""

import importlib.abc
import importlib.machinery
import os
import sys

LOG = os.environ.get("ROVERMARL_WORK_LOG")
TARGET = "rovermarl.runner.chunk"


class _Wrap(importlib.abc.MetaPathFinder, importlib.abc.Loader):
    def find_spec(self, name, path, target=None):
        if name != TARGET:
            return None
        sys.meta_path.remove(self)
        spec = importlib.machinery.PathFinder.find_spec(name, path)
        self.inner = spec.loader
        spec.loader = self
        return spec

    def create_module(self, spec):
        return self.inner.create_module(spec)

    def exec_module(self, module):
        self.inner.exec_module(module)
        original = module.advance

        def advance(cfg, seed, state, n, *args, **kwargs):
            chunk = original(cfg, seed, state, n, *args, **kwargs)
            with open(LOG, "a") as f:
                f.write(f"{seed} {chunk['start']} {chunk['stop']}\n")
            return chunk
        advance.__module__, advance.__qualname__ = original.__module__, original.__qualname__  # pickled by name
        module.advance = advance


if LOG:
    sys.meta_path.insert(0, _Wrap())
