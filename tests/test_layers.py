"""The package's arrows run down only (issue 23): read every ``sinscli`` import with ``ast`` (at module level and
inside functions alike) and check it against the layer order below.

A module may import its own package (``sinscli.io.readers`` -> ``sinscli.io.ros``) and any package of a lower
layer.  Packages of one layer are siblings: neither imports the other (``fusion`` and ``io``: the command line
wires a reader's result into the filter).  A new package goes into the table in one line; a module that is
not in it fails the test, so nothing is left unplaced.
"""
from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1] / "sinscli"

# top to bottom; the names are ``sinscli.<name>`` packages or top-level modules
LAYERS: tuple[tuple[str, ...], ...] = (
    ("cli",),                                  # one module per command: wiring only
    ("batch",),                                # back ends, jobs, batch comparisons, Monte Carlo studies
    ("report",),                               # rendering: tables, figures, HTML (numbers from evaluate/)
    ("evaluate", "align"),                     # errors against a truth, metrics; initial alignment
    ("allan", "sim"),                          # Allan analysis; the exact-truth simulator
    ("fusion", "io"),                          # the GNSS/INS filter; readers and writers (siblings)
    ("gnss",),                                 # raw GNSS kernels (orbits, corrections, SPP), read by io/ and fusion/
    ("nav",),                                  # strapdown kernels, earth model, rotations, IMU statistics
    ("config", "sensors"),                     # the navigation config; the sensor description
    ("inputs", "frames"),                      # input checks, the one YAML loader; frame and angle conventions of files
    ("errors", "types", "units", "layout", "conventions", "__init__"),   # the package's __version__ and cache note
    ("_numba_cache",),                         # where numba caches, imported by the package's __init__
)
RANK = {name: i for i, layer in enumerate(LAYERS) for name in layer}


def _module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT.parent).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts)


def _unit(module: str) -> str:
    """The table entry of a ``sinscli`` module: its package, or the top-level module's name."""
    parts = module.split(".")
    return "__init__" if len(parts) == 1 else parts[1]


def _imports():
    """``(importer, imported module, line, inside a function)`` for every import of a ``sinscli`` module."""
    modules = {_module_name(p): p for p in ROOT.rglob("*.py")}
    out = []
    for name, path in sorted(modules.items()):
        tree = ast.parse(path.read_text(encoding="utf-8"))
        package = name if path.name == "__init__.py" else name.rsplit(".", 1)[0]

        def visit(node, in_function):
            for child in ast.iter_child_nodes(node):
                local = in_function or isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda))
                if isinstance(child, ast.Import):
                    out.extend((name, a.name, child.lineno, in_function) for a in child.names
                               if a.name.split(".")[0] == "sinscli")
                elif isinstance(child, ast.ImportFrom):
                    if child.level:
                        base = package.split(".")[:len(package.split(".")) - child.level + 1]
                        target = ".".join(base + ([child.module] if child.module else []))
                    else:
                        target = child.module or ""
                    if target.split(".")[0] != "sinscli":
                        continue
                    for a in child.names:           # ``from . import coarse`` imports the module sinscli.align.coarse
                        full = f"{target}.{a.name}"
                        out.append((name, full if full in modules else target, child.lineno, in_function))
                visit(child, local)

        visit(tree, False)
    return modules, out


MODULES, IMPORTS = _imports()


def test_every_module_has_a_layer():
    missing = sorted({_unit(m) for m in MODULES} - set(RANK))
    assert not missing, f"add these to LAYERS in {__file__}: {missing}"


def test_the_table_sees_the_imports():
    # the reader itself: known arrows of the tree (a reader that found nothing would pass everything)
    pairs = {(a, b) for a, b, _, _ in IMPORTS}
    assert ("sinscli.fusion.pipeline", "sinscli.nav.pipeline") in pairs or \
        any(a.startswith("sinscli.fusion.") and b.startswith("sinscli.nav.") for a, b in pairs)
    assert ("sinscli.align.coarse", "sinscli.nav.earth") in pairs
    assert ("sinscli.io.readers", "sinscli.io.ros") in pairs                # a function-local import is read too
    assert len(IMPORTS) > 500


def test_arrows_run_down_only():
    bad = []
    for importer, imported, line, _ in IMPORTS:
        a, b = _unit(importer), _unit(imported)
        if a == b or a not in RANK or b not in RANK:
            continue
        if RANK[b] <= RANK[a]:
            kind = "sibling" if RANK[b] == RANK[a] else "up"
            bad.append(f"{importer} (line {line}) -> {imported}: {kind} ({a} -> {b})")
    assert not bad, "imports against the layer order:\n" + "\n".join(bad)


def test_no_import_cycles():
    """No circle among the modules (module-level and function-local imports alike; Tarjan's SCC)."""
    graph: dict[str, set[str]] = {m: set() for m in MODULES}
    for importer, imported, _, _ in IMPORTS:
        if imported in graph and imported != importer:
            graph[importer].add(imported)
    # importing a module runs its packages' __init__ first; those edges are part of the import, not a cycle
    index, low, stack, on, cycles, counter = {}, {}, [], set(), [], [0]

    def strong(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in graph[v]:
            if w not in index:
                strong(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                cycles.append(sorted(comp))

    for v in sorted(graph):
        if v not in index:
            strong(v)
    assert not cycles, f"import cycles: {cycles}"


@pytest.mark.parametrize("src, ok", [
    (("sinscli.fusion.kernel", "sinscli.nav.strapdown"), True),
    (("sinscli.nav.sanity", "sinscli.align.coarse"), False),      # the arrow issue 23 removed
    (("sinscli.io.readers", "sinscli.fusion.standstill"), False),  # siblings
    (("sinscli.config", "sinscli.io.inputs"), False),
])
def test_the_rule_itself(src, ok):
    a, b = (_unit(m) for m in src)
    assert (a == b or RANK[b] > RANK[a]) is ok


# Packages whose function-local imports still wait for their reason (their modules are being reworked by
# other issues; remove a name once its package is done).
REASONS_PENDING = {"cli.fusion_run": "issue 19 (the lead)", "io": "issue 22 (readers, writers)",
                   "align": "issue 19 (the lead)", "fusion": "issue 19 (the lead)", "sim": "the simulator's issue"}


def _local_imports():
    """``(module, line, text, reason)`` of every import inside a function; ``reason`` is the comment on its line
    or on the line above its group of imports."""
    out = []
    for name, path in sorted(MODULES.items()):
        lines = path.read_text(encoding="utf-8").split("\n")
        tree = ast.parse("\n".join(lines))
        for fn in ast.walk(tree):
            if not isinstance(fn, (ast.FunctionDef, ast.AsyncFunctionDef)):
                continue
            for node in ast.walk(fn):
                if not isinstance(node, (ast.Import, ast.ImportFrom)):
                    continue
                text = lines[node.lineno - 1]
                reason = text.split("#", 1)[1].strip() if "#" in text else ""
                k = node.lineno - 2
                while not reason and k >= 0 and lines[k].strip().startswith(("import ", "from ", ")")) \
                        or (k >= 0 and lines[k].rstrip().endswith(",") and not reason):
                    k -= 1
                if not reason and k >= 0 and lines[k].strip().startswith("#"):
                    reason = lines[k].strip().lstrip("#").strip()
                out.append((name, node.lineno, text.strip(), reason))
    return out


def test_function_local_imports_say_why():
    """An import inside a function hides an arrow and costs at every call: each says why it is there (start-up
    of the command line, proven by tests/test_cli_startup.py; an optional or heavy dependency)."""
    missing = [f"{m}:{line}: {text}" for m, line, text, reason in _local_imports()
               if not reason and not any(m == f"sinscli.{k}" or m.startswith(f"sinscli.{k}.") for k in REASONS_PENDING)]
    assert not missing, "function-local imports without a one-line reason:\n" + "\n".join(missing)
