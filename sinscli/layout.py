"""Named layouts of the flat float64 vectors that the numba kernels carry (state, configuration, scratch).

A kernel keeps its state in one ``np.float64`` array and reads it by module-level integer offsets, which numba
freezes into the compiled code as constants (no cost per access).  The offsets are generated here from one
declarative list of ``(name, size)`` fields, consecutive and in order, with the total asserted, so that no
field is numbered by hand, none overlaps another and no slot is left unnamed::

    STATE = Layout("strapdown state", [("S_T", 1), ("S_VEL", 3), ...], total=102)
    (S_T, S_VEL, ...) = STATE.offsets("S_T", "S_VEL", ...)

``tests/test_layout.py`` checks every layout of the package: fields disjoint and covering ``0 .. total``, and
each module constant equal to its field's offset.
"""
from __future__ import annotations


class Layout:
    """Consecutive named fields of a flat vector: ``offset[name]``, ``size[name]``, ``total``."""

    def __init__(self, title: str, fields, total: int | None = None, start: int = 0):
        self.title = title
        self.fields: tuple[tuple[str, int], ...] = tuple((str(n), int(s)) for n, s in fields)
        self.start = int(start)
        self.offset: dict[str, int] = {}
        self.size: dict[str, int] = {}
        at = self.start
        for name, size in self.fields:
            if name in self.offset:
                raise ValueError(f"{title}: field {name} given twice")
            if size < 1:
                raise ValueError(f"{title}: field {name} has size {size}; expected >= 1")
            self.offset[name], self.size[name] = at, size
            at += size
        self.total = at
        if total is not None and at != total:
            raise ValueError(f"{title}: the fields add up to {at}, expected {total}")

    def offsets(self, *names: str) -> tuple[int, ...]:
        """The offsets of ``names`` (each must be a field), in the order given."""
        return tuple(self.offset[n] for n in names)

    def extend(self, title: str, fields, total: int | None = None) -> Layout:
        """A layout that starts where this one ends (the same vector, longer: e.g. the launch-inertial state)."""
        return Layout(title, fields, total, start=self.total)

    def span(self, name: str) -> range:
        """The slots of field ``name``."""
        return range(self.offset[name], self.offset[name] + self.size[name])

    def __len__(self) -> int:
        return self.total - self.start

    def __repr__(self) -> str:
        return f"Layout({self.title!r}, {len(self.fields)} fields, slots {self.start}..{self.total - 1})"
