"""A vector primitive of the neighbourhood walk, written in LLVM IR (a numba intrinsic).

:func:`far_masks` compares the squared distances of :data:`W` consecutive points to three
squared radii and returns the three comparison masks as integers (bit t: point t is
farther). Written as a numba loop, LLVM vectorises the distances but assembles each mask
bit by bit (a masked move and an OR per vector, then a horizontal OR); here the vector
comparison is bit-cast straight to an integer, one mask-register move on AVX-512 (a
movemask elsewhere), which makes :func:`~laser_corners.kernel.neighbourhood.counts` about a third
faster. The arithmetic is the scalar kernel's, lane by lane: (x - xj)·(x - xj) +
(y - yj)·(y - yj) (no fused multiply-add) compared with ``>``, so every bit equals the
scalar test.
"""

from __future__ import annotations

from llvmlite import ir
from numba import types
from numba.core import cgutils
from numba.extending import intrinsic

__all__ = ["W", "far_masks"]

W = 16  # points per mask (16: the fastest of 8, 16 and 32 on the benchmark sets)


@intrinsic
def far_masks(typingctx, px, py, base, xj, yj, r2_a, r2_b, r2_c):  # type: ignore[no-untyped-def]
    """``(ma, mb, mc)``: bit t of ``ma`` is set when the point ``base + t`` (t < :data:`W`)
    lies farther than sqrt(``r2_a``) from (``xj``, ``yj``), i.e. ``(px[base + t] - xj)**2 +
    (py[base + t] - yj)**2 > r2_a``; likewise ``mb``, ``mc``.

    ``px``, ``py``: C-contiguous float64 arrays; the caller guarantees that indices
    ``base`` to ``base + W - 1`` are within both (no bounds check, no wrap-around).
    """
    ok = all(
        isinstance(a, types.Array) and a.dtype == types.float64 and a.layout == "C" and a.ndim == 1
        for a in (px, py)
    )
    scalars = (xj, yj, r2_a, r2_b, r2_c)
    if not ok or not isinstance(base, types.Integer) or any(t != types.float64 for t in scalars):
        return None
    sig = types.UniTuple(types.int64, 3)(px, py, base, xj, yj, r2_a, r2_b, r2_c)

    def codegen(context, builder, signature, args):  # type: ignore[no-untyped-def]
        ax, ay, b, xj_, yj_, ra, rb, rc = args
        vec = ir.VectorType(ir.DoubleType(), W)
        i32 = ir.IntType(32)
        b = context.cast(builder, b, signature.args[2], types.intp)

        def load(value, ty):  # type: ignore[no-untyped-def]
            data = context.make_array(ty)(context, builder, value).data
            ptr = builder.bitcast(cgutils.gep(builder, data, b), vec.as_pointer())
            return builder.load(ptr, align=8)

        def splat(value):  # type: ignore[no-untyped-def]
            undef = ir.Constant(vec, ir.Undefined)
            first = builder.insert_element(undef, value, ir.Constant(i32, 0))
            return builder.shuffle_vector(first, undef, ir.Constant(ir.VectorType(i32, W), [0] * W))

        dx = builder.fsub(load(ax, signature.args[0]), splat(xj_))
        dy = builder.fsub(load(ay, signature.args[1]), splat(yj_))
        d2 = builder.fadd(builder.fmul(dx, dx), builder.fmul(dy, dy))
        masks = []
        for r2 in (ra, rb, rc):
            bits = builder.bitcast(builder.fcmp_ordered(">", d2, splat(r2)), ir.IntType(W))
            masks.append(builder.zext(bits, ir.IntType(64)))
        return context.make_tuple(builder, signature.return_type, masks)

    return sig, codegen
