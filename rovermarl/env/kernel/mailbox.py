"""A mailbox through which the calling thread hands a population to helper threads that wait in compiled code
(numba, no GIL): what :mod:`rovermarl.env.relay` runs, and ``fused.serve`` reads.

Waking a sleeping thread costs this machine 40-50 us on the caller and about 100 us before the helper runs; a helper
that waits for work in Python needs the GIL, which the caller holds. A helper that waits in compiled code reading
the mailbox starts a population's passes within a microsecond of :func:`post`. The box is an int64 array (``BOX``
slots); the arrays of a job go through it as addresses (the caller keeps them alive until :func:`close` returns).

The protocol (every access of a shared slot atomic, sequentially consistent):

- the caller writes the job (addresses, sizes), resets the pass counters, then stores ``STATE = 4*gen + OPEN``;
- a helper that sees an open job it has not served adds 1 to ``INSIDE``, then reads ``STATE`` and ``EPOCH`` again:
  still open and its epoch, it takes passes (``lanes.claim``) until none is left; else it touches nothing. Then it
  takes 1 from ``INSIDE``;
- after its own passes the caller stores ``STATE = 4*gen + CLOSED`` and waits until ``INSIDE`` is down to the
  helpers that failed (``FAILED``): every other helper that saw the job open has finished with its arrays.

``EPOCH`` names the initial conditions and world the helpers were started on; the caller changes it to send them
back to Python. ``AWAKE`` counts the helpers in compiled code: the caller wakes the others.
"""

from __future__ import annotations

import platform

import numpy as np
from llvmlite import ir
from numba import carray, types
from numba.core import cgutils
from numba.extending import intrinsic

from rovermarl.jit import njit

BOX = 16
GEN, STATE, INSIDE, AWAKE, EPOCH, FAILED = 0, 1, 2, 3, 4, 5       # slots of the box, then the job's:
TEAMS, ROWS, COLS, RETURNS, SCORES, SANE, FINAL, FINAL_ROWS, PER_PASS, SEATS = 6, 7, 8, 9, 10, 11, 12, 13, 14, 15
OPEN, CLOSED = 0, 1
_X86 = platform.machine().lower() in ("x86_64", "amd64", "i386", "i686")


def _slot(context, builder, sig, args):
    """A pointer to slot ``args[1]`` of the box ``args[0]`` (no bounds check: the slots above)."""
    ary = context.make_array(sig.args[0])(context, builder, args[0])
    k = context.cast(builder, args[1], sig.args[1], types.intp)
    return cgutils.get_item_pointer(context, builder, sig.args[0], ary, [k])


def _is_box(a) -> bool:
    return isinstance(a, types.Array) and a.dtype == types.int64 and a.ndim == 1 and a.layout == "C"


@intrinsic
def load(typingctx, box, k):
    """``box[k]``, read atomically (sequentially consistent)."""
    if not _is_box(box):
        return None

    def codegen(context, builder, sig, args):
        return builder.load_atomic(_slot(context, builder, sig, args), "seq_cst", 8)
    return types.int64(box, k), codegen


def _write(op: str):
    """An intrinsic ``f(box, k, value)`` that writes ``value`` into slot k atomically (sequentially consistent): a
    store (``op`` "store") or an atomic read-modify-write (``op`` "add": ``box[k] += value``)."""

    def write(typingctx, box, k, value):
        if not _is_box(box):
            return None

        def codegen(context, builder, sig, args):
            v, ptr = context.cast(builder, args[2], sig.args[2], types.int64), _slot(context, builder, sig, args)
            if op == "store":
                builder.store_atomic(v, ptr, "seq_cst", 8)
            else:
                builder.atomic_rmw(op, ptr, v, "seq_cst")
            return context.get_dummy_value()
        return types.void(box, k, value), codegen
    return intrinsic(write)


store = _write("store")     # box[k] = value: what this thread wrote before is seen first
add = _write("add")         # box[k] += value in one step


@intrinsic
def address(typingctx, a):
    """The address of an array's data, as an int64."""
    if not isinstance(a, types.Array):
        return None

    def codegen(context, builder, sig, args):
        return builder.ptrtoint(context.make_array(sig.args[0])(context, builder, args[0]).data, ir.IntType(64))
    return types.int64(a), codegen


@intrinsic
def _pointer(typingctx, addr):
    def codegen(context, builder, sig, args):
        return builder.inttoptr(args[0], cgutils.voidptr_t)
    return types.voidptr(types.int64), codegen


@intrinsic
def pause(typingctx):
    """The CPU's spin-wait hint (x86 ``pause``: a waiting loop leaves the core's resources to others); nothing on
    other CPUs."""
    def codegen(context, builder, sig, args):
        if _X86:
            fn = cgutils.get_or_insert_function(builder.module, ir.FunctionType(ir.VoidType(), []),
                                                "llvm.x86.sse2.pause")
            builder.call(fn, [])
        return context.get_dummy_value()
    return types.void(), codegen


@njit(cache=True)
def post(box, teams, returns, scores, sane, final, per_pass, counters, seats):
    """Open a job of B teams (``fused.evaluate_many``'s arrays: teams (B*N, G) float64, returns (B*E,), scores (B,),
    sane (B,) bool, final (B*E, N, 2) or zero rows), ``per_pass`` teams a pass, its pass counter (1,) reset, for at
    most ``seats`` helpers. Returns the job's number, for :func:`close`. The caller keeps the arrays alive until
    then."""
    gen = load(box, GEN) + 1
    counters[0] = 0
    store(box, TEAMS, address(teams))
    store(box, ROWS, teams.shape[0])
    store(box, COLS, teams.shape[1])
    store(box, RETURNS, address(returns))
    store(box, SCORES, address(scores))
    store(box, SANE, address(sane))
    store(box, FINAL, address(final))
    store(box, FINAL_ROWS, final.shape[0])
    store(box, PER_PASS, per_pass)
    store(box, SEATS, seats)
    store(box, GEN, gen)
    store(box, STATE, 4 * gen + OPEN)
    return gen


@njit(nogil=True, cache=True)
def close(box, gen):
    """Close job ``gen`` and wait until no helper is inside it but those that failed (:func:`fail`); False if any
    did."""
    store(box, STATE, 4 * gen + CLOSED)
    while load(box, INSIDE) > load(box, FAILED):
        pause()
    return load(box, FAILED) == 0


@njit(cache=True)
def fail(box):
    """Count a helper that raised (it stays counted ``INSIDE`` the job it was in)."""
    add(box, FAILED, 1)


@njit(inline="always", cache=True)
def open_job(box, served, epoch):
    """The number of an open job for a helper of ``epoch`` that last served job ``served``, or -1."""
    state = load(box, STATE)
    gen = state // 4
    return gen if state % 4 == OPEN and gen != served and load(box, EPOCH) == epoch else -1


@njit(inline="always", cache=True)
def seated(box):
    """Whether the helpers inside the job are no more than it asked for (``SEATS``: the call's threads - 1)."""
    return load(box, INSIDE) <= load(box, SEATS)


@njit(inline="always", cache=True)
def job_arrays(box, n_ep, n):
    """The arrays of the open job (:func:`post`), as the caller passed them: teams (B*N, G), returns (B*E,), scores
    (B,), sane (B,), final (B*E or 0, N, 2); ``n_ep`` = E episodes, ``n`` = N rovers."""
    rows = load(box, ROWS)
    b = rows // n
    teams = carray(_pointer(load(box, TEAMS)), (rows, load(box, COLS)), np.float64)
    returns = carray(_pointer(load(box, RETURNS)), (b * n_ep,), np.float64)
    scores = carray(_pointer(load(box, SCORES)), (b,), np.float64)
    sane = carray(_pointer(load(box, SANE)), (b,), np.bool_)
    final = carray(_pointer(load(box, FINAL)), (load(box, FINAL_ROWS), n, 2), np.float64)
    return teams, returns, scores, sane, final


@njit(nogil=True, cache=True)
def spin(n):
    """n spin-wait hints (:func:`pause`): what a helper's wait of n reads costs (``relay`` times it once)."""
    for _ in range(n):
        pause()
