"""The one validator family of every YAML section (navigation config, ``fusion:``, ``align:``, scenarios).

Each check takes the source (a file name, or ``command line``), the dotted key and the value, returns the
value in its typed form, and refuses anything else with one line in one style::

    nav.yaml: key navigation.coning: expected one of 1, 2, 3, 4, got 5
    nav.yaml: key fusion.zupt.sigma: expected a number > 0, got 0.0
    nav.yaml: key imu.colour: unknown key; expected one of body, columns, ...

Pure Python (no numpy), so that every layer can use it.
"""
from __future__ import annotations

import math

from .errors import SinsError, num, quote

MAX_VALUE = 1.0e9            # any number of a section: its square stays far from overflow
MAX_COUNT = 2 ** 31 - 1      # largest count (the kernels count in int64)


def got(v) -> str:
    """A value as a message shows it: numbers plainly, text quoted and cut, anything else by its repr."""
    if isinstance(v, bool) or v is None:
        return {True: "true", False: "false", None: "null"}[v]
    if isinstance(v, (int, float)):
        return num(v)
    if isinstance(v, str):
        return quote(v, 60)
    r = repr(v)
    return r if len(r) <= 80 else r[:76] + "..."


def fail(src, key: str, message: str):
    """Raise the one-line refusal ``SRC: key KEY: MESSAGE``."""
    raise SinsError(f"{src}: key {key}: {message}")


def expected(src, key: str, what: str, v):
    """Raise ``SRC: key KEY: expected WHAT, got V``."""
    fail(src, key, f"expected {what}, got {got(v)}")


def _bounds(gt, ge, le, lt) -> str:
    lo = f"({gt:g}" if gt is not None else (f"[{ge:g}" if ge is not None else None)
    hi = f"{lt:g})" if lt is not None else (f"{le:g}]" if le is not None else None)
    if lo and hi:
        return f"a number in {lo}, {hi}"
    if lo:
        return f"a number {'>' if gt is not None else '>='} {lo[1:]}"
    if hi:
        return f"a number {'<' if lt is not None else '<='} {hi[:-1]}"
    return "a finite number"


def is_number(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def number(src, key, v, *, gt=None, ge=None, le=None, lt=None, limit: float = MAX_VALUE) -> float:
    """A finite number within the bounds given (``gt`` >, ``ge`` >=, ``le`` <=, ``lt`` <), and within
    +-``limit``, as a float."""
    if not is_number(v) or not math.isfinite(v):
        expected(src, key, "a finite number" if (gt, ge, le, lt) == (None,) * 4 else _bounds(gt, ge, le, lt), v)
    x = float(v)
    if not abs(x) <= limit:
        expected(src, key, f"a number within +-{limit:g}", v)
    if (gt is not None and not x > gt) or (ge is not None and not x >= ge) or \
            (le is not None and not x <= le) or (lt is not None and not x < lt):
        expected(src, key, _bounds(gt, ge, le, lt), v)
    return x


def optional_number(src, key, v, **bounds) -> float | None:
    """``null`` or :func:`number`."""
    return None if v is None else number(src, key, v, **bounds)


def integer(src, key, v, lo: int = 1, hi: int = MAX_COUNT) -> int:
    """A whole number from ``lo`` to ``hi``."""
    if not isinstance(v, int) or isinstance(v, bool) or not lo <= v <= hi:
        expected(src, key, f"a whole number from {lo} to {hi}", v)
    return int(v)


def boolean(src, key, v) -> bool:
    if not isinstance(v, bool):
        expected(src, key, "true or false", v)
    return v


def choice(src, key, v, choices):
    """One of ``choices`` (text compared in lower case)."""
    if isinstance(v, str):
        v = v.lower()
    if isinstance(v, bool) or v not in choices:
        expected(src, key, f"one of {', '.join(map(str, choices))}", v)
    return v


def optional_text(src, key, v) -> str | None:
    if v is not None and not isinstance(v, str):
        expected(src, key, "a name (text) or null", v)
    return v


def vector(src, key, v, n: int, scalar: bool = True, **bounds) -> tuple:
    """``n`` numbers (each as :func:`number` with ``bounds``), or with ``scalar`` one number for all."""
    if isinstance(v, (list, tuple)):
        if len(v) != n:
            expected(src, key, f"{n} numbers", v)
        return tuple(number(src, f"{key}[{i}]", x, **bounds) for i, x in enumerate(v))
    if not scalar:
        expected(src, key, f"a list of {n} numbers", v)
    return (number(src, key, v, **bounds),) * n


def names(src, key, v) -> tuple:
    """A list of names (text)."""
    if not isinstance(v, (list, tuple)) or not all(isinstance(x, str) for x in v):
        expected(src, key, "a list of names", v)
    return tuple(v)


def mapping(src, key: str, v, keys=None) -> dict:
    """A mapping (``null``: empty) whose keys are among ``keys`` (when given)."""
    if v is None:
        return {}
    if not isinstance(v, dict):
        expected(src, key, "a mapping of keys", v)
    if keys is not None:
        for k in v:
            if k not in keys:
                fail(src, f"{key}.{k}" if key else str(k),
                     f"unknown key; expected one of {', '.join(sorted(map(str, keys)))}")
    return v


def merge(defaults: dict, data, src, prefix: str, raw=()) -> dict:
    """``defaults`` with ``data`` laid over it, nested mappings merged key by key (unknown keys refused);
    the keys in ``raw`` are taken whole."""
    out = {k: (merge(v, None, src, f"{prefix}.{k}", raw) if isinstance(v, dict) and k not in raw else v)
           for k, v in defaults.items()}
    for k, v in mapping(src, prefix, data, defaults).items():
        if isinstance(defaults[k], dict) and k not in raw:
            out[k] = merge(defaults[k], v, src, f"{prefix}.{k}", raw)
        else:
            out[k] = v
    return out


class FrozenMap(dict):
    """A read-only mapping (a frozen section's mapping field): a dict that refuses every change, and pickles
    (a config travels to the workers of a batch)."""

    def _read_only(self, *args, **kwargs):
        raise TypeError(f"{type(self).__name__} is read-only (replace the section instead)")

    __setitem__ = __delitem__ = __ior__ = clear = pop = popitem = setdefault = update = _read_only

    def __reduce__(self):
        return type(self), (dict(self),)


def frozen(d: dict) -> FrozenMap:
    """A read-only copy of a mapping (for a frozen section's mapping fields)."""
    return FrozenMap(d)
