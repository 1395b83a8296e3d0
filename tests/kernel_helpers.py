"""Compiled helpers for the kernel tests only (not part of the package)."""

import math

from numba import njit

from rovermarl.env.kernel.math import FAST, atan2, tanh


@njit(**FAST)
def atan2_array(y, x, out):
    """out (M,) <- the kernel's :func:`atan2` of y, x (M,), in a vectorised loop as in the kernel."""
    for q in range(out.shape[0]):
        out[q] = atan2(y[q], x[q])


@njit(**FAST)
def atan2_ranged_array(y, x, out):
    """out (M,) <- ``atan2(y, x, ranged=True)`` of y, x (M,), vectorised as in the kernel's sensing."""
    for q in range(out.shape[0]):
        out[q] = atan2(y[q], x[q], True)


@njit(**FAST)
def tanh_array(x, out):
    """out (M,) <- the kernel's :func:`tanh` of x (M,), in a vectorised loop as in the kernel."""
    for q in range(out.shape[0]):
        out[q] = tanh(x[q])


@njit(**FAST)
def tanh_finite_array(x, out):
    """out (M,) <- ``tanh(x, finite=True)`` of x (M,), vectorised as in the kernel's MLP."""
    for q in range(out.shape[0]):
        out[q] = tanh(x[q], True)


@njit(cache=True)
def act_libm(genome, obs, hidden, h_buf):
    """MLP forward for one rover with libm tanh: genome (G,), obs (D,) -> (a0, a1); h_buf (H,) scratch."""
    d = obs.shape[0]
    o_b1 = d * hidden
    o_w2 = o_b1 + hidden
    o_b2 = o_w2 + 2 * hidden
    for u in range(hidden):
        h_buf[u] = genome[o_b1 + u]
    for i in range(d):
        v = obs[i]
        row = i * hidden
        for u in range(hidden):
            h_buf[u] += v * genome[row + u]
    z0 = genome[o_b2]
    z1 = genome[o_b2 + 1]
    for u in range(hidden):
        t = math.tanh(h_buf[u])
        z0 += t * genome[o_w2 + 2 * u]
        z1 += t * genome[o_w2 + 2 * u + 1]
    return math.tanh(z0), math.tanh(z1)


@njit(**FAST)
def act_plain(genomes, obs, hidden, out):
    """The MLP as plain loops, with the kernel's tanh and its FMA contraction: genomes (N, G), obs (E, N, D) ->
    out (E, N, 2). Every hidden unit adds all D inputs in index order, one multiply-add each."""
    n_ep, n, d = obs.shape
    o_b1 = d * hidden
    o_w2 = o_b1 + hidden
    o_b2 = o_w2 + 2 * hidden
    for e in range(n_ep):
        for i in range(n):
            g = genomes[i]
            z0 = g[o_b2]
            z1 = g[o_b2 + 1]
            for u in range(hidden):
                h = g[o_b1 + u]
                for k in range(d):
                    h = h + obs[e, i, k] * g[k * hidden + u]
                t = tanh(h)
                z0 = z0 + t * g[o_w2 + 2 * u]
                z1 = z1 + t * g[o_w2 + 2 * u + 1]
            out[e, i, 0] = tanh(z0)
            out[e, i, 1] = tanh(z1)
