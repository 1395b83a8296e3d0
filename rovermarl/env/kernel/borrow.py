"""Arrays that numba does not count references to, for the rollout's step loop (numba intrinsics).

numba counts the references to an array with an atomic add on its memory record wherever a copy of it lives past
a call: each array an inlined hook passes on to a compiled call costs two atomic instructions a step, each of which
also waits for the core's pending stores. :func:`borrow` returns the same array without its record (as
``numba.carray`` of a raw pointer has none), so those counts find nothing to count. The caller keeps the owner
alive, and :func:`keep` marks where its last use is: numba frees an array after its last use.

A borrowed array must not leave the function that borrowed it (not returned, not stored).
"""

from __future__ import annotations

from numba import types
from numba.core import cgutils
from numba.extending import intrinsic


@intrinsic
def borrow(typingctx, a):
    """``a`` (an array) without its memory record: the same data, shape and strides, no reference counting;
    anything else (a plug-in's tuple) as it is."""
    if not isinstance(a, types.Array):
        def same(context, builder, sig, args):
            context.nrt.incref(builder, sig.args[0], args[0])      # a new reference, as numba's own values are
            return args[0]
        return a(a), same

    def codegen(context, builder, sig, args):
        ary = context.make_array(sig.args[0])(context, builder, args[0])
        out = context.make_array(sig.return_type)(context, builder)
        for field in ("data", "shape", "strides", "itemsize", "nitems"):
            setattr(out, field, getattr(ary, field))
        out.meminfo = cgutils.get_null_value(out.meminfo.type)
        out.parent = cgutils.get_null_value(out.parent.type)
        return out._getvalue()
    return a(a), codegen


@intrinsic
def keep(typingctx, owner):
    """A use of ``owner`` here and nothing else: what it owns stays allocated until this point."""
    def codegen(context, builder, sig, args):
        return context.get_dummy_value()
    return types.none(owner), codegen
