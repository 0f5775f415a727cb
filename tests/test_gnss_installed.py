"""The installed package's raw-GNSS commands from a directory outside the repository: the shipped broadcast file
(package data) drives `sins simulate --raw-gnss`, then `sins gnss spp`, `sins info` (see test_installed.py for
when these run and skip)."""
from __future__ import annotations

from test_installed import ROOT, run, sins, workdir  # noqa: F401  (fixtures)


def test_installed_raw_gnss_simulate_spp_info(sins, workdir):  # noqa: F811
    run(sins, ["simulate", str(ROOT / "configs/scenarios/vehicle_drive.yaml"), "--duration", "30", "--raw-gnss",
               str(ROOT / "configs/raw_gnss/urban.yaml"), "-o", "sim", "-q"], workdir)
    for name in ("obs.rnx", "nav.rnx", "gnss_truth.csv"):
        assert (workdir / "sim" / name).stat().st_size > 0
    run(sins, ["gnss", "spp", "sim/obs.rnx", "--nav", "sim/nav.rnx", "-o", "fix.csv", "--elev-mask", "5"], workdir)
    lines = (workdir / "fix.csv").read_text().splitlines()
    assert lines[0].startswith("time,lat,lon,height") and len(lines) > 10
    p = run(sins, ["info", "sim/obs.rnx"], workdir)
    assert "RINEX 3.04 observations" in p.stdout and "GPS" in p.stdout
