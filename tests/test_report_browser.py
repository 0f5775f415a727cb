"""Every report kind (single compare, batch, alignment Monte Carlo) loaded from file:// in headless Chromium.

Debian's ``chromium`` and ``chromium-driver`` driven by selenium (``.ci/run`` installs them with apt when
they are absent).  One browser session and one set of small simulated reports for the whole module.
The reports are written by the installed ``sins`` script from a temporary directory.
"""
from __future__ import annotations

import io
import os
import shutil
import subprocess
import tempfile
from pathlib import Path

import numpy as np
import pytest
import yaml

from batchutil import SINS, write_batch

CHROMIUM, CHROMEDRIVER = "/usr/bin/chromium", "/usr/bin/chromedriver"

webdriver = pytest.importorskip("selenium.webdriver", reason="selenium is not installed (pip install '.[test]')")
if not (os.access(CHROMIUM, os.X_OK) and os.access(CHROMEDRIVER, os.X_OK)):
    pytest.skip(f"{CHROMIUM} / {CHROMEDRIVER} absent (apt-get install chromium chromium-driver; .ci/run does it "
                "where apt can be used)", allow_module_level=True)

from selenium.webdriver.chrome.service import Service  # noqa: E402
from selenium.webdriver.common.action_chains import ActionChains  # noqa: E402
from selenium.webdriver.common.by import By  # noqa: E402

DRIVE = {"name": "drive", "start": {"lat": 30.0, "lon": 114.0, "height": 50.0, "heading": 30.0, "speed": 10.0},
         "imu": {"rate": 50, "sensor": "mems"},
         "gnss": {"rate": 1, "pos_noise": [1.5, 1.5, 3.0], "vel_noise": 0.05, "outages": [[14, 24]]},
         "segments": [{"type": "cruise", "duration": 12}, {"type": "turn", "angle": 90, "duration": 8, "bank": "none"},
                      {"type": "cruise", "duration": 20}]}
REST = {"name": "mc_rest", "start": {"lat": 30.0, "lon": 114.0, "height": 50.0, "heading": 0.0},
        "imu": {"rate": 20, "sensor": {"gyro": {"bias_sigma": 0.01}, "accel": {"bias_sigma": 50}}},
        "gnss": {"rate": 1}, "segments": [{"type": "rest", "duration": 60}], "align": {"method": "inertial"}}
EVIL = "<script>alert(1)<.csv"          # a file name that must be shown, never run


def sins(args, cwd):
    r = subprocess.run([SINS, *map(str, args), "-q"], cwd=cwd, capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr
    return r


@pytest.fixture(scope="module")
def reports(tmp_path_factory):
    d = tmp_path_factory.mktemp("reports")
    (d / "drive.yaml").write_text(yaml.safe_dump(DRIVE))
    sins(["simulate", "drive.yaml", "-o", "sim", "--seed", "3"], d)
    sins(["navigate", "sim/imu.csv", "--init", "sim/init.yaml", "--gnss", "sim/gnss.csv", "--sensor", "mems",
          "-o", "fused.csv"], d)
    sins(["navigate", "sim/imu.csv", "--init", "sim/init.yaml", "-o", EVIL], d)
    sins(["compare", "--truth", "sim/truth.csv", "fused.csv", EVIL, "--gnss", "sim/gnss.csv", "-o", "single"], d)
    write_batch(d / "batch", seeds=3)
    sins(["compare", "batch/batch.yaml", "-o", "batch/out", "--jobs", "1"], d)
    (d / "rest.yaml").write_text(yaml.safe_dump(REST))
    sins(["align", "--monte-carlo", 3, "--scenario", "rest.yaml", "-o", "mc"], d)
    return {"single": d / "single/index.html", "batch": d / "batch/out/index.html",
            "dataset": d / "batch/out/tiny/index.html", "mc": d / "mc/index.html"}


@pytest.fixture(scope="module")
def browser():
    profile = tempfile.mkdtemp(prefix="sins-chromium-")
    opts = webdriver.ChromeOptions()
    opts.binary_location = CHROMIUM
    for a in ("--headless=new", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
              "--disable-background-networking", "--disable-component-update", "--disable-sync",
              "--disable-dev-shm-usage", f"--user-data-dir={profile}", "--window-size=1280,1000"):
        opts.add_argument(a)
    opts.set_capability("goog:loggingPrefs", {"browser": "ALL"})
    drv = webdriver.Chrome(service=Service(CHROMEDRIVER), options=opts)
    try:
        yield drv
    finally:
        drv.quit()
        shutil.rmtree(profile, ignore_errors=True)


def load(drv, path: Path) -> None:
    drv.get_log("browser")                    # drop what an earlier page logged
    drv.get(path.as_uri())
    errors = [e for e in drv.get_log("browser") if e["level"] == "SEVERE"]
    assert not errors, errors
    assert drv.execute_script("return typeof window.sinsPlots") == "object"


def plot_contents(drv) -> list[dict]:
    """For every plot on the page: its id, kind, and what it drew."""
    return drv.execute_script("""
        return Array.from(document.querySelectorAll('.plotbox')).map(function (box) {
          var svg = box.querySelector('svg.plot');
          var lines = Array.from(svg.querySelectorAll('path.line')).filter(function (p) {
            return (p.getAttribute('d') || '').split('L').length > 1; });
          return {id: box.id, kind: svg.getAttribute('class'), lines: lines.length,
                  points: svg.querySelectorAll('g.points circle, g.points path').length,
                  bands: svg.querySelectorAll('path.band').length, boxes: svg.querySelectorAll('g.box rect').length,
                  spans: svg.querySelectorAll('rect.span').length,
                  legend: Array.from(box.querySelectorAll('.legend .item')).map(function (i) {
                    return i.textContent.trim(); })};
        });""")


def assert_not_blank(drv) -> None:
    from PIL import Image
    img = np.asarray(Image.open(io.BytesIO(drv.get_screenshot_as_png())).convert("L"), dtype=float)
    assert img.std() > 10.0, img.std()           # a blank page has std 0; ours 20 to 60
    assert (img < 128).mean() > 0.003            # text and lines (a blank page: 0)


def test_single_report(browser, reports):
    load(browser, reports["single"])
    plots = plot_contents(browser)
    by_id = {p["id"]: p for p in plots}
    assert len(plots) == 11                      # plan view + 10 error plots
    for p in plots:
        assert p["lines"] + p["points"] > 0, p   # every plot drew data
    plan = by_id["plot-plan"]
    # truth + 2 trajectories + GNSS fixes; the file names as given are the legend, the evil one as text
    assert plan["legend"] == ["truth", "fused.csv", EVIL, "GNSS fixes (gnss.csv)"]
    assert plan["lines"] == 3 and plan["points"] > 20
    # the GNSS outage (14-24 s) shaded on every time plot; fused.csv's own sigma as bands
    assert all(p["spans"] == 1 for p in plots if p["id"] != "plot-plan")
    assert by_id["plot-pos_e"]["bands"] == 2 and by_id["plot-att_angle"]["bands"] == 0
    # the file named like a script was not run: only our two script elements exist
    assert browser.execute_script("return document.scripts.length") == 2
    body = browser.find_element(By.TAG_NAME, "body").text
    assert EVIL in body and "Lowest RMS" in body and "C11g - C11n" in body
    assert "direction-cosine matrix" in body and "sins compare:" not in body
    # zoom: drag across the middle of the roll plot; the linked position plot follows to the same x-range
    svg = browser.find_element(By.CSS_SELECTOR, "#plot-att_roll svg")
    before = float(browser.find_element(By.CSS_SELECTOR, "#plot-pos_e svg").get_attribute("data-xmax"))
    browser.execute_script("arguments[0].scrollIntoView({block: 'center'})", svg)
    w = svg.size["width"]
    ActionChains(browser).move_to_element_with_offset(svg, int(-w * 0.1), 0).click_and_hold() \
        .move_by_offset(int(w * 0.25), 0).release().perform()
    roll = browser.find_element(By.CSS_SELECTOR, "#plot-att_roll svg")
    pos = browser.find_element(By.CSS_SELECTOR, "#plot-pos_e svg")
    x0, x1 = float(roll.get_attribute("data-xmin")), float(roll.get_attribute("data-xmax"))
    assert 0.0 < x0 < x1 < before * 0.9
    assert float(pos.get_attribute("data-xmin")) == pytest.approx(x0)
    assert float(pos.get_attribute("data-xmax")) == pytest.approx(x1)
    browser.execute_script("window.scrollTo(0, 0)")
    assert_not_blank(browser)


def _column(drv, table, k: int) -> list[str]:
    return [r.find_elements(By.TAG_NAME, "td")[k].text for r in table.find_elements(By.TAG_NAME, "tr")[1:]]


def test_batch_report(browser, reports):
    load(browser, reports["batch"])
    plots = plot_contents(browser)
    assert len(plots) == 7 and all(p["boxes"] == 2 for p in plots)     # 7 maxima, box per (dataset, method)
    table = browser.find_element(By.CSS_SELECTOR, "table.sortable")
    header = table.find_elements(By.TAG_NAME, "th")
    k = [h.text for h in header].index("max_att_deg")
    header[k].click()
    up = [float(v) for v in _column(browser, table, k)]
    assert len(up) == 6 and up == sorted(up) and up != [float(v) for v in sorted(up, reverse=True)]
    header[k].click()
    down = [float(v) for v in _column(browser, table, k)]
    assert down == sorted(up, reverse=True)
    links = [a.get_attribute("href") for a in table.find_elements(By.TAG_NAME, "a")]
    assert sum(h.endswith("/tiny/index.html") for h in links) == 6
    runs = sorted(h for h in links if "/tiny/runs/" in h)
    assert len(runs) == 6 and len(set(runs)) == 6
    assert_not_blank(browser)
    # a run's own page: self-contained, truth + that run in its plan view
    browser.get_log("browser")
    browser.get(runs[0])
    assert not [e for e in browser.get_log("browser") if e["level"] == "SEVERE"]
    plots = {p["id"]: p for p in plot_contents(browser)}
    assert len(plots) == 11
    # truth, the run, and the GNSS fixes the worker simulated with the run's seed
    assert plots["plot-plan"]["legend"][0] == "truth" and len(plots["plot-plan"]["legend"]) == 3
    assert plots["plot-plan"]["legend"][2].startswith("GNSS fixes (simulated, seed ")
    assert plots["plot-plan"]["points"] >= 3
    assert all(p["lines"] > 0 for p in plots.values())
    # the dataset's page: 3 seeds x 2 methods per run, box plots, its own plan view
    load(browser, reports["dataset"])
    plots = plot_contents(browser)
    by_id = {p["id"]: p for p in plots}
    assert len(by_id["plot-plan"]["legend"]) == 1 + 6
    assert all(p["lines"] + p["points"] + p["boxes"] > 0 for p in plots), plots
    assert sum(p["boxes"] > 0 for p in plots) == 10
    assert_not_blank(browser)


def test_alignment_monte_carlo_report(browser, reports):
    load(browser, reports["mc"])
    plots = plot_contents(browser)
    lines = [p for p in plots if p["kind"] == "plot line"]
    assert lines and all(p["lines"] >= 3 for p in lines)              # 3 runs (and the theory limits)
    assert any(p["boxes"] > 0 for p in plots)
    assert_not_blank(browser)
