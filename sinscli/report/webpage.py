"""A self-contained interactive HTML page: text, tables and SVG plots drawn by a small script of our own.

The page opens offline from the file system: its style sheet and script
(``assets/report.css``, ``assets/report.js``, package data read through
:mod:`importlib.resources`) are inlined, the plots' data sit in one
``<script type="application/json">`` element, and nothing is fetched.  Why our
own ~400 lines of JavaScript rather than a plotting library: see docs/compare.md
("Reports").

Every text goes through :func:`html.escape` (a file named ``<script>.csv`` is
shown, never run); the JSON escapes ``<`` so that no string can close its
script element.  Numbers are written with 6 significant digits; a non-finite
value is never written: it becomes a gap (``null``) and the page says how many
were left out.
"""
from __future__ import annotations

import html
import json
from importlib import resources

import numpy as np

from ..io.atomic import atomic_path

SIG_DIGITS = 6


def asset(name: str) -> str:
    """The text of a file of ``sinscli/report/assets``."""
    return resources.files("sinscli.report").joinpath("assets", name).read_text(encoding="utf-8")


def esc(x) -> str:
    """An HTML attribute value (quotes escaped too)."""
    return html.escape(str(x), quote=True)


def text(x) -> str:
    """HTML text content (``<``, ``>``, ``&`` escaped)."""
    return html.escape(str(x), quote=False)


class _Encoder:
    """JSON with numpy arrays as number lists (``%.6g``), non-finite numbers as ``null`` (counted)."""

    def __init__(self):
        self.omitted = 0

    def array(self, a) -> str:
        a = np.asarray(a, dtype=float).ravel()
        if a.size == 0:
            return "[]"
        ok = np.isfinite(a)
        self.omitted += int(a.size - np.count_nonzero(ok))
        txt = np.char.mod(f"%.{SIG_DIGITS}g", np.where(ok, a, 0.0))
        txt = np.where(ok, txt, "null")
        return "[" + ",".join(txt.tolist()) + "]"

    def encode(self, obj) -> str:
        if isinstance(obj, np.ndarray):
            return self.array(obj)
        if isinstance(obj, dict):
            return "{" + ",".join(f"{self.encode(str(k))}:{self.encode(v)}" for k, v in obj.items()) + "}"
        if isinstance(obj, (list, tuple)):
            return "[" + ",".join(self.encode(v) for v in obj) + "]"
        if isinstance(obj, str):
            return json.dumps(obj).replace("<", "\\u003c").replace(">", "\\u003e").replace("&", "\\u0026")
        if obj is None or isinstance(obj, bool):
            return json.dumps(obj)
        if isinstance(obj, (int, np.integer)):
            return str(int(obj))
        v = float(obj)
        if not np.isfinite(v):
            self.omitted += 1
            return "null"
        return repr(v)


class Page:
    """An HTML page built in order: headings, paragraphs, tables, plots; :meth:`write` writes it."""

    def __init__(self, title: str):
        self.title = title
        self.body: list[str] = [f"<h1>{text(title)}</h1>"]
        self.plots: list[dict] = []

    def h(self, words: str, level: int = 2) -> None:
        self.body.append(f"<h{level}>{text(words)}</h{level}>")

    def p(self, words: str, cls: str = "") -> None:
        self.body.append(f"<p{f' class={chr(34)}{cls}{chr(34)}' if cls else ''}>{text(words)}</p>")

    def items(self, lines: list[str], cls: str = "summary") -> None:
        self.body.append(f"<ul class=\"{cls}\">" + "".join(f"<li>{text(s)}</li>" for s in lines) + "</ul>")

    def raw(self, fragment: str) -> None:
        """Trusted HTML built by this package (every text in it already escaped)."""
        self.body.append(fragment)

    def links(self, label: str, files: list[str]) -> None:
        if files:
            self.body.append(f"<p>{text(label)} " + ", ".join(f"<a href=\"{esc(f)}\">{text(f)}</a>" for f in files)
                             + "</p>")

    def plot(self, spec: dict) -> None:
        """A plot (see ``assets/report.js`` for the fields); ``spec['id']`` must be unique on the page."""
        self.plots.append(spec)
        self.body.append(f"<div class=\"plotbox\" id=\"{esc(spec['id'])}\"><h3>{text(spec.get('title', ''))}</h3></div>")

    def render(self) -> str:
        enc = _Encoder()
        data = enc.encode({"plots": self.plots})
        body = list(self.body)
        if enc.omitted:
            body.insert(1, f"<p class=\"note\">{enc.omitted} non-finite value(s) were left out of the plots "
                           "(drawn as gaps).</p>")
        if self.plots:
            body.insert(2 if enc.omitted else 1,
                        "<p class=\"hint\">Plots: drag to zoom (time plots zoom together), double-click to "
                        "reset, click a legend entry to hide or show it.</p>")
        return ("<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n"
                f"<title>{text(self.title)}</title>\n<style>\n{asset('report.css')}</style>\n</head>\n<body>\n"
                + "\n".join(body)
                + f"\n<script type=\"application/json\" id=\"sins-data\">{data}</script>\n"
                + f"<script>\n{asset('report.js')}</script>\n</body>\n</html>\n")

    def write(self, path) -> None:
        """Write the page atomically."""
        text = self.render()
        with atomic_path(path) as tmp:
            tmp.write_text(text, encoding="utf-8")


def table(header: list[str], rows: list[list], sortable: bool = False, failed: list[bool] | None = None,
          num_format: str = "{:.5E}", titles: list[str] | None = None) -> str:
    """An HTML table.  Cells: str, int, float (``num_format``, ``-`` when not finite; the exact value kept
    in ``data-v`` for sorting), None (empty), or (text, href) for a link."""
    cls = " class=\"sortable\"" if sortable else ""
    head = "".join(f"<th{f' title={chr(34)}{esc(titles[k])}{chr(34)}' if titles and titles[k] else ''}>{text(h)}</th>"
                   for k, h in enumerate(header))
    out = [f"<table{cls}>", f"<tr>{head}</tr>"]
    for k, row in enumerate(rows):
        rc = " class=\"failed\"" if failed and failed[k] else ""
        cells = []
        for c in row:
            if isinstance(c, tuple):
                cells.append(f"<td><a href=\"{esc(c[1])}\">{text(c[0])}</a></td>")
            elif c is None:
                cells.append("<td></td>")
            elif isinstance(c, (float, np.floating)):
                v = float(c)
                cells.append(f"<td class=\"num\" data-v=\"{v!r}\">{num_format.format(v)}</td>" if np.isfinite(v)
                             else "<td class=\"num\">-</td>")
            elif isinstance(c, (int, np.integer)):
                cells.append(f"<td class=\"num\">{int(c)}</td>")
            else:
                cells.append(f"<td>{text(c)}</td>")
        out.append(f"<tr{rc}>" + "".join(cells) + "</tr>")
    out.append("</table>")
    return "\n".join(out)
