"""The kernels' named vector layouts (``sinscli/layout.py``): every layout of the package has disjoint fields
covering its slots, and every module constant is its field's offset (no hand-numbered slot left)."""
import importlib
import pkgutil

import pytest

import sinscli
from sinscli.layout import Layout


def _layouts():
    """``(module, name, layout)`` of every Layout, in the module that names its fields as constants."""
    mods = [importlib.import_module(m.name) for m in pkgutil.walk_packages(sinscli.__path__, "sinscli.")
            if not m.name.startswith("sinscli.cli")]
    found = {}
    for mod in mods:
        for name, value in vars(mod).items():
            if isinstance(value, Layout) and all(hasattr(mod, f) for f, _ in value.fields):
                found.setdefault(id(value), (mod.__name__, name, value))
    return sorted(found.values(), key=lambda x: (x[0], x[1]))


LAYOUTS = _layouts()


def test_the_package_layouts_are_found():
    names = {(m, n) for m, n, _ in LAYOUTS}
    assert ("sinscli.nav.strapdown", "STATE") in names and ("sinscli.nav.inertial", "I_STATE") in names


@pytest.mark.parametrize("module, name, layout", LAYOUTS, ids=[f"{m}.{n}" for m, n, _ in LAYOUTS])
def test_fields_are_disjoint_and_cover_the_vector(module, name, layout):
    owner = [None] * layout.total
    for field, _ in layout.fields:
        for k in layout.span(field):
            assert owner[k] is None, f"{name}: slot {k} in {owner[k]} and {field}"
            owner[k] = field
    assert all(o is not None for o in owner[layout.start:]), f"{name}: unnamed slots"


@pytest.mark.parametrize("module, name, layout", LAYOUTS, ids=[f"{m}.{n}" for m, n, _ in LAYOUTS])
def test_module_constants_are_the_field_offsets(module, name, layout):
    mod = importlib.import_module(module)
    for field, _ in layout.fields:
        assert getattr(mod, field) == layout.offset[field], field
    # no other constant of the same family (prefix) numbered by hand beside the layout
    prefixes = {f.split("_")[0] + "_" for f, _ in layout.fields}
    known = {f for _, _, lay in LAYOUTS for f, _ in lay.fields}
    stray = [k for k, v in vars(mod).items() if any(k.startswith(p) for p in prefixes) and k.isupper()
             and type(v) is int and k not in known]
    assert not stray, f"{module}: constants outside the layout: {stray}"


def test_layout_refuses_a_wrong_total_or_a_repeated_field():
    lay = Layout("x", [("A", 1), ("B", 3)], total=4)
    assert lay.offsets("B", "A") == (1, 0) and list(lay.span("B")) == [1, 2, 3] and len(lay) == 4
    more = lay.extend("y", [("C", 2)], total=6)
    assert more.offset["C"] == 4 and more.start == 4 and len(more) == 2
    with pytest.raises(ValueError, match="add up to 4, expected 5"):
        Layout("x", [("A", 1), ("B", 3)], total=5)
    with pytest.raises(ValueError, match="given twice"):
        Layout("x", [("A", 1), ("A", 3)])
    with pytest.raises(ValueError, match="size 0"):
        Layout("x", [("A", 0)])
