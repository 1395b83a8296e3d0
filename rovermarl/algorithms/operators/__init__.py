"""Operators of CC-(1+1)-ES, one config group each: ``mutation``, ``selection``, ``k`` (k-selectors), ``team``."""
