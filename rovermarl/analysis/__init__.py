"""Analysis of finished sweeps: reading them (:mod:`~rovermarl.analysis.sweep`), compact results
(:mod:`~rovermarl.analysis.export`, :mod:`~rovermarl.analysis.results`), method comparisons
(:mod:`~rovermarl.analysis.claims`) and paper-style figures (:mod:`~rovermarl.analysis.figures`)."""
