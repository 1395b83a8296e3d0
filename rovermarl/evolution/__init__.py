"""CC-(1+1)-ES: mutation, selection, k-selectors, team compositions and the generation loop."""

from rovermarl.evolution.ccea import History, Parts, Run, build, evolve

__all__ = ["History", "Parts", "Run", "build", "evolve"]
