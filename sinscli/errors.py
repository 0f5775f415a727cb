"""The one exception type a user ever sees: a one-line message, exit status 2; and how user text and
numbers are written into messages."""
from __future__ import annotations

import numbers
import os
import re

MAX_MESSAGE = 480        # characters of a message; longer ones are cut (a giant header, a huge value)
# numpy 2 writes scalars as np.float64(0.01): a message shows the number alone, wherever it was formatted
_NUMPY_REPR = re.compile(r"np\.(?:float|int|uint|complex|str_|bool)\w*\(([^()]*)\)")


class SinsError(Exception):
    """Bad input or an impossible request.

    The message is a single line that names the file, row or field and what was
    expected. The CLI prints it as ``sins: error: <message>`` and exits with 2.
    """

    exit_code = 2

    def __init__(self, message: str):
        text = _NUMPY_REPR.sub(r"\1", " ".join(str(message).split()))
        super().__init__(shorten(text))


def shorten(text: str, limit: int = MAX_MESSAGE) -> str:
    """``text`` cut to ``limit`` characters in its middle, at spaces: the start (the file, the line) and the
    end (what to do) are kept, and no word is cut."""
    if len(text) <= limit:
        return text
    keep = limit - 5
    head, tail = text[:keep * 2 // 3], text[len(text) - keep // 3:]
    if " " in head[len(head) // 2:]:
        head = head[:head.rindex(" ")]
    if " " in tail[:len(tail) // 2]:
        tail = tail[tail.index(" ") + 1:]
    return f"{head} ... {tail}"


def quote(text, limit: int = 60) -> str:
    """``'text'`` for a message, cut to ``limit`` characters and with unprintable characters escaped."""
    s = repr(str(text))
    return s if len(s) <= limit else s[:limit - 4] + "...'"


def printable(text) -> str:
    """A path (or text) as it is shown in a message or written into a file: a byte of the name that is
    not UTF-8 (Linux allows any) as ``\\xNN``, so that every text output stays valid UTF-8."""
    s = os.fspath(text) if isinstance(text, os.PathLike) else str(text)
    try:
        s.encode("utf-8")
        return s
    except UnicodeEncodeError:
        return os.fsencode(s).decode("utf-8", "backslashreplace")


def num(x) -> str:
    """A number written plainly for a message: ``0.01``, ``1e+308``, ``nan`` (never ``np.float64(0.01)``)."""
    if isinstance(x, bool):
        return str(x)
    if isinstance(x, numbers.Integral):
        s = str(int(x))
        return s if len(s) <= 24 else f"{s[:12]}... ({len(s)} digits)"
    try:
        return repr(float(x))
    except (TypeError, ValueError, OverflowError):
        return quote(x)
