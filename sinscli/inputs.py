"""Every input path is checked here before it is opened, and every YAML file is read by one safe loader.

:func:`input_file` refuses, up front and naming the file, what would otherwise block or fail deep in
a library: a missing file, a directory, a FIFO (an ``open`` would wait forever for a writer), a device
or socket, an unreadable file.

:func:`load_yaml` is the one YAML reader of the package (init, config, scenario, batch, sensor, bag
metadata): strict UTF-8, bounded size, nesting depth and alias expansion, integers that fit int64 and
no NaN or infinite float anywhere, each refusal naming the file, line and column.

The record of the running command's inputs (:func:`reset_inputs`, :func:`note_input`) lives here too, so
that every layer (the config, the sensor description) can read files without importing ``io/``.
"""
from __future__ import annotations

import os
import stat
from pathlib import Path
from urllib.parse import quote as url_quote

import yaml

from .errors import SinsError, quote

MAX_YAML_BYTES = 4 << 20          # a config, scenario or batch file is a few kB
MAX_YAML_DEPTH = 64               # nesting of mappings and lists
MAX_YAML_NODES = 100_000          # nodes after alias expansion ("billion laughs")
MAX_YAML_INT = 2 ** 63 - 1

_KIND = {stat.S_IFIFO: "a FIFO", stat.S_IFCHR: "a character device", stat.S_IFBLK: "a block device",
         stat.S_IFSOCK: "a socket"}


# The inputs of the running command: its path arguments and options (registered by the CLI,
# ``sinscli/cli/base.py``) and every file a reader opened (:func:`input_file`).  Every output (``io/atomic.py``:
# ``prepare_output``, and each file ``staged_dir`` moves into place) is checked against them, so that no ``-o``
# ever overwrites a log, a config or a truth it reads (issue 10).
# Only while a command runs (library code that reads a file and writes it back is not refused).
_INPUTS: dict[str, Path] = {}
_ACTIVE = [False]


def reset_inputs(paths=()) -> None:
    """Start a command's record of inputs (the CLI calls it as each command starts) with ``paths``."""
    _INPUTS.clear()
    _ACTIVE[0] = True
    for p in paths:
        note_input(p)


def end_inputs() -> None:
    """End the record (the command is done): no check until the next :func:`reset_inputs`."""
    _INPUTS.clear()
    _ACTIVE[0] = False


def note_input(path) -> None:
    """Remember ``path`` as an input of the running command (its real path: symlinks and ``..`` resolved)."""
    if path is None or not _ACTIVE[0]:
        return
    try:
        key = os.path.realpath(os.fspath(path))
    except (TypeError, ValueError, OSError):
        return
    _INPUTS.setdefault(key, Path(path))


def command_inputs() -> dict[str, Path]:
    """The inputs recorded for the running command: real path -> the path as given (empty when none runs)."""
    return _INPUTS


def input_file(path, what: str = "file", allow_dir: bool = False) -> Path:
    """``path`` after checking that it is a readable regular file (or a directory when ``allow_dir``)."""
    p = Path(path)
    try:
        st = p.stat()
    except FileNotFoundError:
        raise SinsError(f"{p}: {what} not found") from None
    except OSError as exc:
        raise SinsError(f"{p}: cannot read the {what} ({exc.strerror or type(exc).__name__})") from None
    if stat.S_ISDIR(st.st_mode):
        if allow_dir:
            note_input(p)
            return p
        raise SinsError(f"{p}: is a directory, expected a {what}")
    if not stat.S_ISREG(st.st_mode):
        kind = _KIND.get(stat.S_IFMT(st.st_mode), "not a regular file")
        raise SinsError(f"{p}: is {kind}, expected a regular {what} (a FIFO or device is not read)")
    if not os.access(p, os.R_OK):
        raise SinsError(f"{p}: cannot read the {what} (permission denied)")
    note_input(p)                    # no output of this command may overwrite it (io/atomic.check_not_input)
    return p


def native_path(path, mode: str = "rb"):
    """``path`` as pyarrow takes it: the text, or, for a name that is not valid UTF-8 (Linux allows any
    bytes but NUL and '/'; Python holds the others as surrogates), a pyarrow file opened on the name's
    bytes in ``mode``, since pyarrow encodes every path text as UTF-8.  The caller closes a file it gets
    (:func:`closing_native`)."""
    text = os.fspath(path)
    try:
        text.encode("utf-8")
        return text
    except UnicodeEncodeError:
        import pyarrow as pa   # only for a name that is not UTF-8: pyarrow is not for --help
        return pa.OSFile(os.fsencode(text), mode)


def closing_native(source) -> None:
    """Close what :func:`native_path` opened (a path text needs nothing)."""
    if not isinstance(source, str):
        source.close()


def sqlite_uri(path, mode: str = "ro") -> str:
    """A SQLite ``file:`` URI of any path: its bytes percent-encoded (a '?', '#' or '%' in a name, or a
    byte that is not UTF-8, would otherwise end or garble the URI)."""
    return f"file:{url_quote(os.fsencode(os.path.abspath(path)))}?mode={mode}"


def _where(src, mark) -> str:
    return f"{src}: line {mark.line + 1}, column {mark.column + 1}" if mark is not None else f"{src}"


class _BoundedLoader(yaml.SafeLoader):
    """SafeLoader with bounded nesting and expansion, int64 integers and finite floats."""

    src = "<yaml>"

    def __init__(self, stream):
        super().__init__(stream)
        self._depth = 0

    def compose_node(self, parent, index):
        self._depth += 1
        try:
            if self._depth > MAX_YAML_DEPTH:
                raise SinsError(f"{_where(self.src, self.peek_event().start_mark)}: nested more than "
                                f"{MAX_YAML_DEPTH} levels deep")
            return super().compose_node(parent, index)
        finally:
            self._depth -= 1

    def get_single_node(self):
        node = super().get_single_node()
        self._keys: dict[int, str] = {}      # scalar node -> its key path, for the messages
        if node is not None:
            sizes: dict[int, int] = {}

            def size(n, path: str) -> int:
                key = id(n)
                if key not in sizes:
                    sizes[key] = 0           # (a recursive alias counts once)
                    self._keys[key] = path
                    if isinstance(n, yaml.SequenceNode):
                        total = sum(size(x, f"{path}[{i}]") for i, x in enumerate(n.value))
                    elif isinstance(n, yaml.MappingNode):
                        total = sum(size(k, path) + size(v, f"{path}.{k.value}" if path else str(k.value))
                                    for k, v in n.value)
                    else:
                        total = 0
                    sizes[key] = min(1 + total, MAX_YAML_NODES + 1)
                return sizes[key]

            if size(node, "") > MAX_YAML_NODES:
                raise SinsError(f"{self.src}: expands to more than {MAX_YAML_NODES} values (anchors and aliases)")
        return node

    def _at(self, node) -> str:
        """``file: line L, column C: key.path`` of a scalar node."""
        key = getattr(self, "_keys", {}).get(id(node))
        return _where(self.src, node.start_mark) + (f": {key}" if key else "")

    def construct_yaml_int(self, node):
        digits = node.value.replace("_", "").lstrip("+-")
        if len(digits) > 20:
            raise SinsError(f"{self._at(node)}: integer {quote(node.value, 30)} is out of range "
                            f"(at most {MAX_YAML_INT})")
        value = super().construct_yaml_int(node)
        if abs(value) > MAX_YAML_INT:
            raise SinsError(f"{self._at(node)}: integer {value} is out of range "
                            f"(at most {MAX_YAML_INT})")
        return value

    def construct_yaml_float(self, node):
        value = super().construct_yaml_float(node)
        if value != value or value in (float("inf"), float("-inf")):
            raise SinsError(f"{self._at(node)}: {quote(node.value, 30)} is not a finite number")
        return value


_BoundedLoader.add_constructor("tag:yaml.org,2002:int", _BoundedLoader.construct_yaml_int)
_BoundedLoader.add_constructor("tag:yaml.org,2002:float", _BoundedLoader.construct_yaml_float)


def parse_yaml(text: str, src: str):
    """Parse YAML text with the bounds of :func:`load_yaml` (``src`` names it in messages)."""
    if text.startswith("\ufeff"):
        text = text[1:]
    loader = None
    try:
        loader = _BoundedLoader(text)
        loader.src = src
        return loader.get_single_data()
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        if isinstance(exc, yaml.reader.ReaderError):
            line = text.count("\n", 0, exc.position) + 1
            raise SinsError(f"{src}: line {line}: character #x{exc.character:04x} is not allowed in YAML") from None
        problem = getattr(exc, "problem", None) or type(exc).__name__
        raise SinsError(f"{_where(src, mark)}: not valid YAML ({problem})") from None
    except RecursionError:
        raise SinsError(f"{src}: nested too deeply") from None
    finally:
        if loader is not None:
            loader.dispose()


def load_yaml(path, what: str = "YAML file"):
    """Read a YAML file (see the module docstring for the checks); an empty file gives None."""
    p = input_file(path, what)
    if p.stat().st_size > MAX_YAML_BYTES:
        raise SinsError(f"{p}: {p.stat().st_size} bytes; a {what} is at most {MAX_YAML_BYTES} bytes")
    try:
        data = p.read_bytes()
    except OSError as exc:
        raise SinsError(f"{p}: cannot read the {what} ({exc.strerror or type(exc).__name__})") from None
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as exc:
        line = data[:exc.start].count(b"\n") + 1
        col = exc.start - (data.rfind(b"\n", 0, exc.start) + 1) + 1
        raise SinsError(f"{p}: line {line}, column {col}: byte 0x{data[exc.start]:02x} is not UTF-8 "
                        f"(save the file as UTF-8)") from None
    return parse_yaml(text, str(p))
