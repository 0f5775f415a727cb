"""Taylor jets in time: a value with its first and second time derivatives.

A :class:`Jet` holds ``c = (x, dx/dt, d2x/dt2)`` (or fewer: order 0, 1 or 2)
as numpy arrays of one common shape.  Arithmetic (``+ - * / ** @``) and the
numpy functions ``sin cos tan arctan arctan2 sqrt exp log square`` propagate
the derivatives exactly (Leibniz and chain rule), through
``__array_ufunc__``, so that plain formulas written for numpy arrays, such as
:func:`sinscli.nav.earth.radii_py` and :func:`sinscli.nav.earth.gravity_py`,
run unchanged on jets.  This is forward-mode automatic differentiation: the
derivatives are exact to rounding, never finite differences.  The values of the functions and the
matrix products are those of :mod:`sinscli.sim.pinned` (the same bits on every CPU).
"""
from __future__ import annotations

import numpy as np

from . import pinned as pm

_BINOM = ((1,), (1, 1), (1, 2, 1))


def _as_array(x):
    return np.asarray(x, dtype=float)


class Jet:
    """Value and time derivatives ``c[0], c[1], c[2]`` (order = len(c) - 1 <= 2)."""

    __slots__ = ("c",)
    __array_priority__ = 1000

    def __init__(self, c):
        c = tuple(_as_array(x) for x in c)
        if not 1 <= len(c) <= 3:
            raise ValueError("a Jet holds 1 to 3 Taylor terms (order 0..2)")
        self.c = c

    # ---- construction -------------------------------------------------
    @classmethod
    def const(cls, x, order: int = 1):
        """A constant: derivatives zero."""
        x = _as_array(x)
        return cls((x,) + tuple(np.zeros_like(x) for _ in range(order)))

    @classmethod
    def time(cls, t, order: int = 1):
        """The independent variable t itself: ``(t, 1, 0)``."""
        t = _as_array(t)
        c = [t]
        if order >= 1:
            c.append(np.ones_like(t))
        if order >= 2:
            c.append(np.zeros_like(t))
        return cls(c)

    # ---- properties ---------------------------------------------------
    @property
    def order(self) -> int:
        return len(self.c) - 1

    @property
    def v(self):
        return self.c[0]

    @property
    def d1(self):
        return self.c[1]

    @property
    def d2(self):
        return self.c[2]

    @property
    def shape(self):
        return self.c[0].shape

    @property
    def T(self):
        """Swap the last two axes (matrix transpose) of every term."""
        return Jet(tuple(np.swapaxes(x, -1, -2) for x in self.c))

    def __repr__(self):
        return f"Jet(order={self.order}, shape={self.shape})"

    def __getitem__(self, idx):
        return Jet(tuple(x[idx] for x in self.c))

    def truncate(self, order: int):
        """The same jet with derivatives above ``order`` dropped."""
        return Jet(self.c[: order + 1])

    def deriv(self):
        """The jet of the time derivative (one order less)."""
        if self.order < 1:
            raise ValueError("an order-0 jet has no derivative")
        return Jet(self.c[1:])

    def sum(self, axis=None):
        return Jet(tuple(x.sum(axis=axis) for x in self.c))

    def reshape(self, *shape):
        return Jet(tuple(x.reshape(*shape) for x in self.c))

    # ---- arithmetic ---------------------------------------------------
    def __add__(self, other):
        return _add(self, other)

    __radd__ = __add__

    def __sub__(self, other):
        return _add(self, _neg(other))

    def __rsub__(self, other):
        return _add(_neg(self), other)

    def __neg__(self):
        return _neg(self)

    def __pos__(self):
        return self

    def __mul__(self, other):
        return _mul(self, other, np.multiply)

    __rmul__ = __mul__

    def __truediv__(self, other):
        if isinstance(other, Jet):
            return _mul(self, _reciprocal(other), np.multiply)
        return Jet(tuple(x / _as_array(other) for x in self.c))

    def __rtruediv__(self, other):
        return _mul(_reciprocal(self), other, np.multiply)

    def __pow__(self, p):
        if isinstance(p, Jet):
            return np.exp(p * np.log(self))
        p = float(p)
        x = self.c[0]
        return _compose(self, lambda: pm.power(x, p), lambda: p * pm.power(x, p - 1.0),
                        lambda: p * (p - 1.0) * pm.power(x, p - 2.0))

    def __matmul__(self, other):
        return _mul(self, other, pm.matmul)

    def __rmatmul__(self, other):
        return _mul(other, self, pm.matmul)

    # ---- numpy functions ----------------------------------------------
    def __array_ufunc__(self, ufunc, method, *inputs, **kwargs):
        if method != "__call__" or kwargs.get("out") is not None:
            return NotImplemented
        if ufunc in _BINARY:
            return _BINARY[ufunc](*inputs)
        if ufunc in _UNARY:
            return _UNARY[ufunc](inputs[0])
        return NotImplemented


def _lift(x, order: int) -> Jet:
    return x if isinstance(x, Jet) else Jet.const(x, order)


def _add(a, b):
    if not isinstance(a, Jet):
        a, b = b, a
    if not isinstance(b, Jet):
        b = _as_array(b)
        return Jet((a.c[0] + b,) + a.c[1:])
    n = min(a.order, b.order)
    return Jet(tuple(a.c[k] + b.c[k] for k in range(n + 1)))


def _neg(a):
    if isinstance(a, Jet):
        return Jet(tuple(-x for x in a.c))
    return -_as_array(a)


def _mul(a, b, op):
    """Leibniz rule ``(ab)^(n) = sum_k C(n,k) a^(k) b^(n-k)`` for ``op`` = multiply or matmul."""
    if not isinstance(a, Jet):
        a = _as_array(a)
        return Jet(tuple(op(a, x) for x in b.c))
    if not isinstance(b, Jet):
        b = _as_array(b)
        return Jet(tuple(op(x, b) for x in a.c))
    n = min(a.order, b.order)
    out = []
    for m in range(n + 1):
        term = op(a.c[0], b.c[m])
        for k in range(1, m + 1):
            p = op(a.c[k], b.c[m - k])
            term = term + (p if _BINOM[m][k] == 1 else _BINOM[m][k] * p)
        out.append(term)
    return Jet(out)


def _compose(g: Jet, f0, f1, f2) -> Jet:
    """Chain rule for ``F(g)``; ``f0, f1, f2`` are thunks giving ``F, F', F''`` at ``g``'s value."""
    c = [f0()]
    if g.order >= 1:
        d1 = f1()
        c.append(d1 * g.c[1])
        if g.order >= 2:
            c.append(f2() * g.c[1] * g.c[1] + d1 * g.c[2])
    return Jet(c)


def _reciprocal(g: Jet) -> Jet:
    r = 1.0 / g.c[0]
    return _compose(g, lambda: r, lambda: -r * r, lambda: 2.0 * r * r * r)


def _sin(g):
    x = g.c[0]
    s = pm.sin(x)
    return _compose(g, lambda: s, lambda: pm.cos(x), lambda: -s)


def _cos(g):
    x = g.c[0]
    c = pm.cos(x)
    return _compose(g, lambda: c, lambda: -pm.sin(x), lambda: -c)


def _tan(g):
    t = pm.tan(g.c[0])
    sec2 = 1.0 + t * t
    return _compose(g, lambda: t, lambda: sec2, lambda: 2.0 * t * sec2)


def _arctan(g):
    x = g.c[0]
    r = 1.0 / (1.0 + x * x)
    return _compose(g, lambda: pm.arctan(x), lambda: r, lambda: -2.0 * x * r * r)


def _sqrt(g):
    s = np.sqrt(g.c[0])
    return _compose(g, lambda: s, lambda: 0.5 / s, lambda: -0.25 / (s * g.c[0]))


def _exp(g):
    e = pm.exp(g.c[0])
    return _compose(g, lambda: e, lambda: e, lambda: e)


def _log(g):
    x = g.c[0]
    return _compose(g, lambda: pm.log(x), lambda: 1.0 / x, lambda: -1.0 / (x * x))


def _square(g):
    return _mul(g, g, np.multiply)


def _arctan2(y, x):
    """``atan2(y, x)``: derivative ``(x y' - y x') / (x^2 + y^2)``."""
    n = max(y.order if isinstance(y, Jet) else 0, x.order if isinstance(x, Jet) else 0)
    y, x = _lift(y, n), _lift(x, n)
    n = min(y.order, x.order)
    c = [pm.arctan2(y.c[0], x.c[0])]
    if n >= 1:
        r2 = x.c[0] * x.c[0] + y.c[0] * y.c[0]
        num = x.c[0] * y.c[1] - y.c[0] * x.c[1]
        c.append(num / r2)
        if n >= 2:
            dnum = x.c[0] * y.c[2] - y.c[0] * x.c[2]
            dr2 = 2.0 * (x.c[0] * x.c[1] + y.c[0] * y.c[1])
            c.append((dnum * r2 - num * dr2) / (r2 * r2))
    return Jet(c)


def _true_divide(a, b):
    if isinstance(a, Jet):
        return a / b
    return _mul(_reciprocal(b), a, np.multiply)


_UNARY = {
    np.negative: _neg, np.positive: lambda g: g, np.sin: _sin, np.cos: _cos, np.tan: _tan,
    np.arctan: _arctan, np.sqrt: _sqrt, np.exp: _exp, np.log: _log, np.square: _square,
}
_BINARY = {
    np.add: _add,
    np.subtract: lambda a, b: _add(a, _neg(b)),
    np.multiply: lambda a, b: _mul(a, b, np.multiply),
    np.matmul: lambda a, b: _mul(a, b, pm.matmul),
    np.true_divide: _true_divide,
    np.arctan2: _arctan2,
    np.power: lambda a, b: a ** b if isinstance(a, Jet) else np.exp(b * pm.log(a)),
}


# ---- helpers on jets ---------------------------------------------------

def stack(items, axis: int = -1) -> Jet:
    """``np.stack`` of jets (and constants) term by term."""
    n = min(j.order for j in items if isinstance(j, Jet))
    items = [_lift(j, n) for j in items]
    shape = np.broadcast_shapes(*(j.shape for j in items))
    return Jet(tuple(np.stack([np.broadcast_to(j.c[k], shape) for j in items], axis=axis)
                     for k in range(n + 1)))


def polynomial(coeffs, u: Jet) -> Jet:
    """``P(u) = sum_i coeffs[i] u^i`` on a jet ``u``: Horner for ``P, P', P''`` and the chain rule.

    Cheaper than building the polynomial from jet products term by term.
    """
    p = np.polynomial.polynomial
    coeffs = np.asarray(coeffs, dtype=float)
    d1 = p.polyder(coeffs)
    u0 = u.c[0]
    return _compose(u, lambda: p.polyval(u0, coeffs), lambda: p.polyval(u0, d1),
                    lambda: p.polyval(u0, p.polyder(d1)))


def axis_rotation(axis: int, angle) -> Jet:
    """Elementary rotation matrix jet ``R_axis(angle)`` (active, right-handed), shape (..., 3, 3).

    ``R_x = [[1,0,0],[0,c,-s],[0,s,c]]`` and cyclic permutations; ``angle`` a jet.
    """
    s, c = np.sin(angle), np.cos(angle)
    i, j, k = axis, (axis + 1) % 3, (axis + 2) % 3
    terms = []
    for n in range(angle.order + 1):
        m = np.zeros(angle.shape + (3, 3))
        if n == 0:
            m[..., i, i] = 1.0
        m[..., j, j] = c.c[n]
        m[..., k, k] = c.c[n]
        m[..., j, k] = -s.c[n]
        m[..., k, j] = s.c[n]
        terms.append(m)
    return Jet(terms)


def vee(skew_jet_value):
    """The vector ``w`` of a skew-symmetric array ``[w x]`` (..., 3, 3), averaging both halves."""
    k = skew_jet_value
    return 0.5 * np.stack([k[..., 2, 1] - k[..., 1, 2],
                           k[..., 0, 2] - k[..., 2, 0],
                           k[..., 1, 0] - k[..., 0, 1]], axis=-1)
