"""Runs and jobs, algorithm-neutral: one chunk of one run (:mod:`~rovermarl.runner.chunk`), the checks of a composed
config (:mod:`~rovermarl.runner.validate`) and one Hydra job with resume and summary (:mod:`~rovermarl.runner.job`)."""

from rovermarl.runner.chunk import Evaluation, Parts, Run, advance, build

__all__ = ["Evaluation", "Parts", "Run", "advance", "build"]
