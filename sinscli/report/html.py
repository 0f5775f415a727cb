"""``index.html``: the error table and the figures on one page, opening from the file system.

Only relative links (the figures and files sit beside the page), no scripts,
no network resources.
"""
from __future__ import annotations

import html

from ..io.atomic import atomic_path
import numpy as np

from .errors import CONSISTENCY_UNITS, ROW_UNITS, ConsistencyTable, ErrorTable
from .tables import CONSISTENCY_LABELS, ROW_LABELS

_STYLE = """
body { font-family: sans-serif; margin: 1.5em; max-width: 70em; }
table { border-collapse: collapse; margin: 0.5em 0 1.5em 0; }
th, td { border: 1px solid #bbb; padding: 0.2em 0.6em; }
td.num { text-align: right; font-family: monospace; }
tr.failed td { background: #fdd; }
img { max-width: 100%; border: 1px solid #ddd; margin: 0.3em 0; }
.note { color: #555; }
"""


def _e(x) -> str:
    return html.escape(str(x), quote=True)


def _page(title: str, body: list[str]) -> str:
    return ("<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n"
            f"<title>{_e(title)}</title>\n<style>{_STYLE}</style>\n</head>\n<body>\n"
            + "\n".join(body) + "\n</body>\n</html>\n")


def error_table_html(table: ErrorTable) -> str:
    """The seed-000 table as an HTML table (values in ``%.5E`` like the paper)."""
    out = ["<table>", "<tr><th>No.</th><th>Quantity</th><th>Unit</th>"
           + "".join(f"<th>{_e(m)}</th>" for m in table.methods) + "</tr>"]
    for r, key in enumerate(table.rows):
        label = ROW_LABELS[key].replace("\\|", "|")
        out.append(f"<tr><td>{r + 1}</td><td>{_e(label)}</td><td>{_e(ROW_UNITS[key])}</td>"
                   + "".join(f"<td class=\"num\">{v:.5E}</td>" for v in table.values[r]) + "</tr>")
    out.append("</table>")
    return "\n".join(out)


def consistency_table_html(cons: ConsistencyTable) -> str:
    """The navigators' sigma consistency (fraction inside 3 sigma, average NEES) as a heading and a table."""
    out = ["<h2>Consistency of the navigators' own 1-sigma</h2>",
           "<p class=\"note\">Fraction of epochs whose error lies inside +-3 sigma (0.9973 for an honest Gaussian "
           "claim) and the average NEES over the three axes (3 for an honest claim).</p>",
           "<table>", "<tr><th>Quantity</th><th>Unit</th>" + "".join(f"<th>{_e(m)}</th>" for m in cons.methods) + "</tr>"]
    for r, key in enumerate(cons.rows):
        cells = "".join("<td class=\"num\">-</td>" if np.isnan(v) else f"<td class=\"num\">{v:.4f}</td>"
                        for v in cons.values[r])
        out.append(f"<tr><td>{_e(CONSISTENCY_LABELS[key])}</td><td>{_e(CONSISTENCY_UNITS[key])}</td>{cells}</tr>")
    out.append("</table>")
    return "\n".join(out)


def report_page(title: str, table: ErrorTable, figures: list[str], files: list[str],
                notes: list[str] = (), extra_html: str = "") -> str:
    """The HTML text of one report: notes, the table, links to the files, the figures."""
    body = [f"<h1>{_e(title)}</h1>"]
    body += [f"<p class=\"note\">{_e(n)}</p>" for n in notes]
    body.append("<h2>Trajectory metrics</h2>" if table.epoch is None else
                f"<h2>Errors (truth minus navigation) at t = {float(table.epoch)!r} s</h2>")
    body.append(error_table_html(table))
    body.append(extra_html)
    body.append("<p>Files: " + ", ".join(f"<a href=\"{_e(f)}\">{_e(f)}</a>" for f in files) + "</p>")
    body.append("<h2>Figures</h2>")
    body += [f"<p><img src=\"{_e(f)}\" alt=\"{_e(f)}\"></p>" for f in figures]
    return _page(title, body)


def write_report_html(path, title: str, table: ErrorTable, figures: list[str], files: list[str],
                      notes: list[str] = (), extra_html: str = "") -> None:
    """Write :func:`report_page` atomically."""
    text = report_page(title, table, figures, files, notes, extra_html)
    with atomic_path(path) as tmp:
        tmp.write_text(text, encoding="utf-8")


def summary_html(lines: list[str]) -> str:
    """Summary sentences as a list."""
    return "<h2>Summary</h2>\n<ul>\n" + "".join(f"<li>{_e(s)}</li>\n" for s in lines) + "</ul>"


def simple_table_html(header: list[str], rows: list[list], failed: list[bool] | None = None) -> str:
    """A plain HTML table; rows flagged in ``failed`` are highlighted.  Cells may be (text, href)."""
    out = ["<table>", "<tr>" + "".join(f"<th>{_e(h)}</th>" for h in header) + "</tr>"]
    for k, row in enumerate(rows):
        cls = " class=\"failed\"" if failed and failed[k] else ""
        cells = []
        for c in row:
            if isinstance(c, tuple):
                cells.append(f"<td><a href=\"{_e(c[1])}\">{_e(c[0])}</a></td>")
            elif c is None:
                cells.append("<td></td>")
            elif isinstance(c, float):
                cells.append(f"<td class=\"num\">{c:.5E}</td>")
            else:
                cells.append(f"<td>{_e(c)}</td>")
        out.append(f"<tr{cls}>" + "".join(cells) + "</tr>")
    out.append("</table>")
    return "\n".join(out)


def write_summary_html(path, title: str, sections: list[tuple[str, str]], notes: list[str] = ()) -> None:
    """A summary page: ``sections`` are (heading, html) pairs."""
    body = [f"<h1>{_e(title)}</h1>"] + [f"<p class=\"note\">{_e(n)}</p>" for n in notes]
    for heading, content in sections:
        body += [f"<h2>{_e(heading)}</h2>", content]
    with atomic_path(path) as tmp:
        tmp.write_text(_page(title, body), encoding="utf-8")
