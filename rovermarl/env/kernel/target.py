"""512-bit vectors where the CPU has them: the numba target features the kernel compiles with, chosen at import.

LLVM tunes many AVX-512 CPUs (Intel's Skylake-SP to Sapphire Rapids) with ``prefer-256-bit``, so its vectoriser uses
256-bit registers on 512-bit hardware (AMD's Zen 4 is tuned for 512 already). :func:`configure` runs on import, which
:mod:`rovermarl.env.kernel` does first, before numba compiles anything of rovermarl: on a CPU with AVX-512 it sets
numba's target features to the host's plus ``-prefer-256-bit``, elsewhere it does nothing. Results stay bit-identical:
the vector width changes how many episodes one instruction holds, never what an episode computes (no reduction is
reordered; ``tests/test_kernel_target.py``).

``ROVERMARL_VECTORS``: ``auto`` (default; ``NUMBA_CPU_NAME`` or ``NUMBA_CPU_FEATURES``, when set, rule), ``512`` (also
with ``NUMBA_CPU_NAME``, e.g. to build for an Intel target elsewhere) or ``off`` (numba's own choice); another value
is warned about in one line and read as ``auto``. numba's cache keys on the features, so each choice compiles once; if
numba compiled something before rovermarl was imported, this changes nothing but the cache key.
"""

from __future__ import annotations

import os
import warnings

CHOICES = ("auto", "512", "off")


def features(host: str, choice: str = "auto", cpu_name: str | None = None, cpu_features: str | None = None
             ) -> str | None:
    """The numba target features for host features ``host`` (LLVM's comma-separated ``+x,-y`` string), or None to
    leave numba's own.

    >>> features("+avx2,+avx512f,+fma")
    '+avx2,+avx512f,+fma,-prefer-256-bit'
    >>> features("+avx2,-avx512f,+fma") is None, features("+avx512f", cpu_name="skylake-avx512") is None
    (True, True)
    >>> features("+avx512f", "512", cpu_name="skylake-avx512")
    '+avx512f,-prefer-256-bit'
    """
    if choice not in CHOICES:
        raise ValueError(f"ROVERMARL_VECTORS={choice!r}: must be one of {', '.join(CHOICES)}")
    if choice == "off" or cpu_features or (choice == "auto" and cpu_name) or "+avx512f" not in host.split(","):
        return None
    return f"{host},-prefer-256-bit"


def configure() -> str | None:
    """Apply :func:`features` to numba's config for this process (see the module doc); returns what it set."""
    from numba.core import codegen, config

    choice = os.environ.get("ROVERMARL_VECTORS", "auto")
    if choice not in CHOICES:
        warnings.warn(f"ROVERMARL_VECTORS={choice!r}: must be one of {', '.join(CHOICES)}; using auto", stacklevel=3)
        choice = "auto"
    chosen = features(codegen.get_host_cpu_features(), choice, os.environ.get("NUMBA_CPU_NAME"),
                      os.environ.get("NUMBA_CPU_FEATURES"))
    if chosen is not None:
        os.environ["NUMBA_CPU_FEATURES"] = chosen          # Ray workers and subprocesses inherit the choice
        config.reload_config()
    return chosen


def debug_build_warning() -> str | None:
    """The warning given at import when numba builds with debug info (``NUMBA_DEBUGINFO=1``, or
    ``NUMBA_ENABLE_PROFILING=1`` without ``NUMBA_DEBUGINFO=0``), else None: such a build neither inlines the kernel's
    ``tanh`` and ``atan2`` nor vectorises its loops (about 5x slower here), cached apart (:mod:`rovermarl.jit`)."""
    from numba.core import config

    if not config.DEBUGINFO_DEFAULT:
        return None
    message = ("numba builds with debug info (NUMBA_DEBUGINFO / NUMBA_ENABLE_PROFILING): the kernel is not vectorised "
               "(about 5x slower; cached apart from the plain build); to profile it, set NUMBA_DEBUGINFO=0")
    warnings.warn(message, stacklevel=3)
    return message


SET = configure()    # on import, which the kernel package does first: the features set, or None
DEBUG_BUILD = debug_build_warning()
