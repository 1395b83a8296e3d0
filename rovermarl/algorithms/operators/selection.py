"""Acceptance rules of the (1+1)-ES, built from ``conf/selection/*.yaml``."""

from __future__ import annotations

from rovermarl.errors import ConfigError
from rovermarl.jit import njit


class Selection:
    """Accept the children when ``f_child >= f_parent`` (soft) or ``f_child > f_parent`` (strict)."""

    def __init__(self, strict: bool = False):
        if not isinstance(strict, bool):
            raise ConfigError("strict", strict, "must be true or false")
        self.strict = strict

    def __call__(self, f_child: float, f_parent: float) -> bool:
        return keeps(f_child, f_parent, self.strict)


@njit(cache=True)
def keeps(f_child, f_parent, strict):
    """Whether the children are kept: ``f_child > f_parent`` if ``strict``, else ``f_child >= f_parent``.

    >>> keeps(1.0, 1.0, False), keeps(1.0, 1.0, True)
    (True, False)
    """
    return f_child > f_parent if strict else f_child >= f_parent
