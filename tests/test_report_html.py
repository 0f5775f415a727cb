"""The report page without a browser: headline figures, summary words, escaping, non-finite values, no network
resource; the alignment figures' robust y-range and supplied-heading marker."""
import re

import numpy as np
import pytest

from sinscli.report.align_figures import robust_range, series_figure
from sinscli.report.compare_page import display_unit, row_meaning, summary_lines
from sinscli.report.digest import SeriesDigest
from sinscli.evaluate.errors import ROWS, ErrorSeries, headline_errors
from sinscli.report.webpage import Page, asset


def _series(pos, vel, angle_rad):
    n = len(angle_rad)
    z = np.zeros((n, 3))
    return ErrorSeries(time=np.arange(n, dtype=float), dC=np.zeros((n, 3, 3)), pos_enu_m=pos, vel_enu_mps=vel,
                       att_n_rad=z, att_rph_rad=z, angle_rad=angle_rad)


def test_headline_errors_against_closed_form():
    n = 1000
    t = np.linspace(0.0, 2.0 * np.pi, n, endpoint=False)
    pos = np.column_stack([3.0 * np.ones(n), 4.0 * np.ones(n), 2.0 * np.sin(t)])      # |EN| = 5, U = 2 sin
    vel = np.column_stack([np.zeros(n), np.zeros(n), np.full(n, -0.5)])
    ang = np.radians(np.linspace(0.0, 1.0, n))
    h = headline_errors(_series(pos, vel, ang))
    np.testing.assert_allclose(h[:2], [1.0, np.sqrt(np.mean(np.linspace(0, 1, n) ** 2))], rtol=1e-12)
    np.testing.assert_allclose(h[2:4], [5.0, 5.0], rtol=1e-12)
    np.testing.assert_allclose(h[4:6], [2.0, np.sqrt(2.0)], rtol=1e-5)     # rms of 2 sin over a period
    np.testing.assert_allclose(h[6:8], [0.5, 0.5], rtol=1e-12)


def test_summary_names_the_files_and_the_best_method():
    ts = (np.array([10.0, 20.0]), {})
    d = {"a": SeriesDigest({}, ts, headline=np.array([1.0, 0.5, 2, 1, 3, 1, 4, 1])),
         "b": SeriesDigest({}, ts, headline=np.array([2.0, 0.25, 1, 2, 3, 1, 4, 1]))}
    lines = summary_lines(d, {"a": "a.csv", "b": "runs/b.csv"}, "truth.csv", None)
    assert lines[0] == "Compared 2 trajectory file(s) with the truth truth.csv: a.csv, runs/b.csv."
    assert "10.0 to 20.0 s" in lines[1]
    assert lines[2].endswith("Lowest RMS: runs/b.csv.") and lines[2].startswith("Attitude error angle: a.csv max 1 deg")
    assert lines[3].endswith("Lowest RMS: a.csv.")
    assert lines[4].endswith("Equal RMS (within 0.1 %): a.csv, runs/b.csv.")


def test_table_words_and_units():
    assert all(row_meaning(k) != k for k in ROWS)
    assert "direction-cosine matrix" in row_meaning("C23") and "row 2, column 3" in row_meaning("C23")
    assert display_unit("1") == "" and display_unit("m/s") == "m/s"


def test_page_escapes_names_and_never_writes_non_finite_numbers(tmp_path):
    evil = "<script>alert(1)</script>.csv"
    page = Page(f"{evil} against the truth")
    page.items([f"file {evil}"])
    page.plot({"id": "p", "kind": "line", "title": evil, "series": [
        {"name": evil, "x": np.arange(5.0), "y": np.array([1.0, np.nan, np.inf, -np.inf, 2.0])}]})
    page.write(tmp_path / "index.html")
    text = (tmp_path / "index.html").read_text()
    assert text.count("<script") == 2                     # the data block and our script, nothing injected
    assert "&lt;script&gt;alert(1)&lt;/script&gt;.csv" in text
    assert "\\u003cscript\\u003ealert(1)\\u003c/script\\u003e.csv" in text     # inside the JSON
    data = re.search(r'id="sins-data">(.*?)</script>', text, re.S).group(1)
    assert "[1,null,null,null,2]" in data and not re.search(r"NaN|Infinity", data)
    assert "3 non-finite value(s) were left out of the plots" in text
    # self-contained: no resource is fetched from anywhere
    assert not re.search(r'(src|href)\s*=\s*"(https?:)?//', text)
    assert asset("report.js") in text and asset("report.css") in text


def test_robust_range_leaves_out_a_startup_transient():
    t = np.linspace(0.0, 300.0, 3001)
    rng = np.random.default_rng(1)
    runs = 0.01 * rng.standard_normal((5, t.size))
    runs[:, t < 5.0] += np.linspace(150.0, 0.0, int(np.sum(t < 5.0)))            # +150 deg start-up
    lo, hi = robust_range(t, [runs], keep=[-0.044, 0.044])
    assert -0.1 < lo < -0.044 and 0.044 < hi < 0.1
    assert robust_range(t, [0.01 * rng.standard_normal((5, t.size))], keep=[-0.044, 0.044]) is None


def test_supplied_heading_is_a_marker_not_a_jump():
    t = np.linspace(0.0, 60.0, 61)
    eul = np.column_stack([np.full(61, 0.1), np.full(61, -0.2), np.full(61, 12.0)])
    eul[:3, 2] = [150.0, 80.0, 20.0]                  # start-up transient
    final = np.array([0.1, -0.2, 41.5])
    eul[-1] = final                                   # the written state holds the user's heading
    fig = series_figure(t, eul, "x", sigma_deg=np.array([0.01, 0.01, np.nan]), final_deg=final,
                        heading_supplied=True)
    ax = fig.axes[2]
    by_label = {ln.get_label(): ln for ln in ax.get_lines()}
    est = by_label["estimate"]
    assert est.get_ydata()[-1] == 12.0 and len(est.get_xdata()) == 60          # no jump to 41.5
    mark = by_label["supplied heading (--heading)"]
    assert list(mark.get_xdata()) == [60.0] and list(mark.get_ydata()) == [41.5]
    lo, hi = ax.get_ylim()
    assert lo < 12.0 and 41.5 < hi < 150.0                                     # the transient is clipped
    roll = {ln.get_label(): ln for ln in fig.axes[0].get_lines()}
    assert "written state" in roll and len(roll["estimate"].get_xdata()) == 60
