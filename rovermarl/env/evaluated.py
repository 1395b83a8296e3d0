"""What an evaluation of a team returns: :class:`Evaluated`, its score with what the evaluation measured."""

from __future__ import annotations

import numpy as np


class Evaluated(float):
    """A team's score F, as an evaluation returns it, with what the evaluation measured: ``final_xy`` (E, N, 2), the
    rovers' final positions (None when the run keeps none). Pass it on as it is to the observer (``accepted``,
    ``evaluated``): that is how the observer sees the team it is told about. It pickles as a plain float.

    >>> f = Evaluated(2.5, None)
    >>> f + 1, f.final_xy
    (3.5, None)
    """

    def __new__(cls, score: float, final_xy: np.ndarray | None):
        self = super().__new__(cls, score)
        self.final_xy = final_xy
        return self

    def __reduce__(self):
        return float, (float(self),)
