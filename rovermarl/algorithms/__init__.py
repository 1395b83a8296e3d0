"""Learners over a rover team, one plug-in each (see :mod:`rovermarl.algorithms.base`), and their operators."""

from rovermarl.algorithms.base import Algorithm, AlgorithmError, Evaluated, NullObserver, Series

__all__ = ["Algorithm", "AlgorithmError", "Evaluated", "NullObserver", "Series"]
