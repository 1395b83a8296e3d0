"""Acceptance rules of the (1+1)-ES, built from ``conf/selection/*.yaml``."""

from __future__ import annotations

from rovermarl.errors import ConfigError


class Selection:
    """Accept the children when ``f_child >= f_parent`` (soft) or ``f_child > f_parent`` (strict)."""

    def __init__(self, strict: bool = False):
        if not isinstance(strict, bool):
            raise ConfigError("strict", strict, "must be true or false")
        self.strict = strict

    def __call__(self, f_child: float, f_parent: float) -> bool:
        return f_child > f_parent if self.strict else f_child >= f_parent
