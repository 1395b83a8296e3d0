"""Learners over a rover team, one plug-in each (see :mod:`rovermarl.algorithms.base`), and their operators."""

from rovermarl.algorithms.base import (
    Algorithm,
    AlgorithmError,
    Evaluator,
    KernelInputs,
    Measured,
    NullObserver,
    Observer,
    RunState,
    Series,
)
from rovermarl.env.streams import RunStreams

__all__ = ["Algorithm", "AlgorithmError", "Evaluator", "KernelInputs", "Measured", "NullObserver", "Observer",
           "RunStreams", "Series", "RunState"]
