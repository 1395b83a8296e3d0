"""Analysis of finished sweeps: paper-style figures (:mod:`rovermarl.analysis.figures`)."""
