"""Register-tiled multiply-add loops for the MLP's two layers, written in LLVM IR (numba intrinsics).

numba vectorises innermost loops only, so a hidden unit's sum over the input rows (a chain of dependent multiply-adds)
goes through memory once per pass over the episodes. :func:`hidden_tile` keeps a tile of ``UNITS`` hidden units x
``EPISODES`` episodes in vector registers for the whole sum: from the units' biases, per input row one vector load of
the row's episodes, one broadcast weight per unit and ``UNITS`` fused multiply-adds; :func:`output_tile` does the
same for the output layer's 2 units. Each (unit, episode) still adds its rows in index order, each as one
``fma(x, w, h)``, which is what the ``FAST`` contraction of ``h + x * w`` computes: bit-identical to the plain loops
(``tests/test_kernel_math.py``). A tile's vectors hold 64 bytes of episodes (:func:`lanes`), which LLVM splits into
the target's registers (one 512-bit or two 256-bit ones per unit).

Worth 1.86x a call: ``python benchmarks/intrinsics.py --pairs 3`` (``plain_tiles``: ``stages._mlp``'s plain loops
for every tile), float64 duo ``World.evaluate`` 85.8-90.0 against 46.8-48.5 us, alternated processes on one pinned
core of a loaded machine (load average 8.7, 2026-12-06; ``docs/PERFORMANCE.md``).
"""

from __future__ import annotations

from llvmlite import ir
from numba import types
from numba.core import cgutils
from numba.extending import intrinsic, overload

from rovermarl.jit import njit

UNITS = 8          # hidden units per tile (the output layer's tiles have its 2 units)
EPISODES = 8       # float64 episodes per tile: one 64-byte vector per unit (16 for float32)

_I64 = ir.IntType(64)


def lanes(a) -> int:
    """Episodes per tile for arrays of ``a``'s dtype: one 64-byte vector, 8 float64 or 16 float32."""
    return 64 // a.itemsize


@overload(lanes, inline="always")
def _lanes(a):
    n = 512 // a.dtype.bitwidth
    return lambda a: n


def _const(x: int) -> ir.Constant:
    return ir.Constant(_I64, x)


def _tile(units: int, vectors: int = 1):
    """An intrinsic ``tile(acc, x, genome, rows, nr, q0, ne, wstride, w0, u0, ep, e0, b0)`` over ``units`` units:
    ``acc[(u0 + j)*ep + e] = genome[b0 + j]`` plus ``x[k*ne + q0 + e] * genome[w0 + k*wstride + j]`` for each row
    ``k`` of ``rows[:nr]`` (or ``0 .. nr-1`` if rows is None) in order, for j < units and the ``vectors`` x
    :func:`lanes` episodes e from ``e0`` (the sums start from the biases in registers; ``units * vectors``
    independent chains). acc, x, genome of one float dtype and rows int64 must be contiguous, and the tile must lie
    inside them (the callers check)."""

    @intrinsic
    def tile(typingctx, acc, x, genome, rows, nr, q0, ne, wstride, w0, u0, ep, e0, b0):
        i64 = types.int64
        if not (acc.dtype == x.dtype == genome.dtype and isinstance(acc.dtype, types.Float)):
            return None
        sig = types.void(acc, x, genome, rows, i64, i64, i64, i64, i64, i64, i64, i64, i64)
        width, bits = 512 // acc.dtype.bitwidth, acc.dtype.bitwidth
        vec = ir.VectorType(ir.DoubleType() if bits == 64 else ir.FloatType(), width)
        align = bits // 8

        def codegen(context, builder, signature, args):
            acc_a, x_a, genome_a, rows_a, nr, q0, ne, wstride, w0, u0, ep, e0, b0 = args
            hp, op, gp = (cgutils.create_struct_proxy(t)(context, builder, value=v).data
                          for t, v in zip(signature.args[:3], (acc_a, x_a, genome_a), strict=True))
            every = signature.args[3] == types.none        # rows None: every row, 0 .. nr-1
            rp = None if every else cgutils.create_struct_proxy(signature.args[3])(context, builder, value=rows_a).data
            add, mul = builder.add, builder.mul

            def vector_at(base, offset):
                return builder.bitcast(builder.gep(base, [offset]), vec.as_pointer())

            fma = cgutils.get_or_insert_function(builder.module, ir.FunctionType(vec, [vec] * 3),
                                                 f"llvm.fma.v{width}f{bits}")
            slots = [vector_at(hp, add(mul(add(u0, _const(j)), ep), add(e0, _const(v * width))))
                     for j in range(units) for v in range(vectors)]
            splat = ir.Constant(ir.VectorType(ir.IntType(32), width), [0] * width)

            def broadcast(offset):                  # genome[offset] in every lane
                w = builder.insert_element(ir.Constant(vec, ir.Undefined), builder.load(builder.gep(gp, [offset])),
                                           ir.Constant(ir.IntType(32), 0))
                return builder.shuffle_vector(w, ir.Constant(vec, ir.Undefined), splat)

            start = [broadcast(add(b0, _const(j))) for j in range(units) for _ in range(vectors)]
            entry = builder.block
            loop = builder.append_basic_block("tile.loop")
            done = builder.append_basic_block("tile.done")
            builder.cbranch(builder.icmp_signed(">", nr, _const(0)), loop, done)

            builder.position_at_end(loop)                       # for r in range(nr): k = rows[r]
            r = builder.phi(_I64)
            chains = units * vectors                            # chain c = j * vectors + v
            acc = [builder.phi(vec) for _ in range(chains)]
            k = r if every else builder.load(builder.gep(rp, [r]))
            base = add(add(mul(k, ne), q0), e0)
            xs = [builder.load(vector_at(op, add(base, _const(v * width))), align=align) for v in range(vectors)]
            row = add(mul(k, wstride), w0)
            ws = [broadcast(add(row, _const(j))) for j in range(units)]
            nxt = [builder.call(fma, [xs[c % vectors], ws[c // vectors], acc[c]]) for c in range(chains)]
            r_next = add(r, _const(1))
            r.add_incoming(_const(0), entry)
            r.add_incoming(r_next, loop)
            for c in range(chains):
                acc[c].add_incoming(start[c], entry)
                acc[c].add_incoming(nxt[c], loop)
            builder.cbranch(builder.icmp_signed("<", r_next, nr), loop, done)

            builder.position_at_end(done)
            final = [builder.phi(vec) for _ in range(chains)]  # phis first: LLVM wants them atop the block
            for c in range(chains):
                final[c].add_incoming(start[c], entry)
                final[c].add_incoming(nxt[c], loop)
                builder.store(final[c], slots[c], align=align)
            return context.get_dummy_value()

        return sig, codegen

    return tile


_hidden = _tile(UNITS)
_output = _tile(2)
_output2 = _tile(2, 2)


@njit(inline="always")
def hidden_tile(hid, obs, genome, rows, nr, q0, ne, hidden, u0, ep, e0, g0, b0):
    """The hidden layer's sums for the tile of units ``u0 .. u0+UNITS-1`` and episodes ``e0 .. e0+lanes(hid)-1``:
    ``hid[u*ep + e] = g[b0 + u] + obs[k*ne + q0 + e] * g[g0 + k*hidden + u] + ...`` over the rows ``k`` of
    ``rows[:nr]`` in order, where g is the genome array read as flat memory (``g0``, ``b0``: a rover's row and its
    biases in it). hid (H*E,), obs (D*N*E,) feature-major, genome (G,) or (N, G) of one float dtype, rows (D,)
    int64; the caller keeps the tile inside the arrays (``u0 + UNITS <= hidden``, ``e0 + lanes <= ep``) and every
    array contiguous (it checks the genome's strides; the others are its own buffers)."""
    _hidden(hid, obs, genome, rows, nr, q0, ne, hidden, g0 + u0, u0, ep, e0, b0 + u0)


@njit(inline="always")
def output_tile(hid, genome, hidden, w0, ep, e0, b0):
    """The output layer's sums for the tile of episodes ``e0 .. e0+lanes(hid)-1``, into the two rows after the
    hidden units: ``hid[(hidden + j)*ep + e] = g[b0 + j] + hid[u*ep + e] * g[w0 + 2*u + j] + ...`` for
    u = 0 .. hidden-1 in order and j = 0, 1 (g: the genome array as flat memory). hid ((H+2)*E,), genome
    contiguous."""
    _output(hid, hid, genome, None, hidden, 0, ep, 2, w0, hidden, ep, e0, b0)


@njit(inline="always")
def output_tile2(hid, genome, hidden, w0, ep, e0, b0):
    """:func:`output_tile` for the episodes ``e0 .. e0+2*lanes(hid)-1`` at once: four independent chains of
    multiply-adds instead of two, the same sums."""
    _output2(hid, hid, genome, None, hidden, 0, ep, 2, w0, hidden, ep, e0, b0)
