"""Named layouts of the flat float64 vectors the numba kernels carry their state in.

A kernel's state, configuration and scratch live in plain arrays (no Python objects per sample); a
:class:`Layout` gives each field of such an array its offset from a declarative ``(name, size)`` list,
with the total asserted, so that no two fields overlap and no offset is numbered by hand::

    CV = Layout("fusion config", [("nx", 1), ("gate", 3), ...], size=47)
    C_NX, C_GATE = CV.nx, CV.gate          # module-level ints: numba freezes them at compile time

``tests/test_layouts.py`` checks every layout of the package for overlaps and totals.
"""
from __future__ import annotations


class Layout:
    """Offsets of the fields ``(name, size)`` laid out in order from 0; ``size`` the total."""

    def __init__(self, name: str, fields, size: int | None = None):
        self.name = name
        self.fields: list[tuple[str, int]] = []
        self._offset: dict[str, int] = {}
        o = 0
        for fname, n in fields:
            if fname in self._offset:
                raise ValueError(f"layout {name}: field {fname!r} declared twice")
            if not isinstance(n, int) or n < 1:
                raise ValueError(f"layout {name}: field {fname!r} has size {n!r}")
            self._offset[fname] = o
            self.fields.append((fname, n))
            o += n
        self.size = o
        if size is not None and size != o:
            raise ValueError(f"layout {name}: fields take {o} slots, declared {size}")

    def __getattr__(self, fname: str) -> int:
        try:
            return self.__dict__["_offset"][fname]
        except KeyError:
            raise AttributeError(f"layout {self.__dict__.get('name')}: no field {fname!r}") from None

    def span(self, fname: str) -> range:
        """The slots of a field."""
        o = self._offset[fname]
        return range(o, o + dict(self.fields)[fname])

    def slots(self) -> list[str]:
        """The field owning each slot (for the overlap test and debugging)."""
        out = []
        for fname, n in self.fields:
            out.extend([fname] * n)
        return out
