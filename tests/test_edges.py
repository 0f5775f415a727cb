"""The edges of the Earth (issue 22): drives across the antimeridian and near (not at) both poles, plain and
fused, against the simulator's exact truth, in every output format; GNSS fixes at a pole refused as the init
reader refuses them; no writer emits a longitude outside [-180, 180) or a latitude beyond +-90; every
longitude difference taken modulo a turn (nav/earth.py: wrap_lon, dlon)."""
from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
import yaml

from test_contract import refused, sins

from sinscli.io.atomic import NonFiniteOutput
from sinscli.io.foxglove import read_trajectory_mcap
from sinscli.io.geo import read_geojson, read_kml
from sinscli.io.tum import read_tum
from sinscli.io.trajectory import read_trajectory, write_trajectory
from sinscli.nav.earth import dlon, dlon_nb, lla_to_local_enu, wrap_lon
from sinscli.evaluate.errors import position_error_enu
from sinscli.types import Trajectory

FORMATS = ("csv", "parquet", "mcap", "tum", "geojson", "kml")


def _scenario(d: Path, name: str, lat: float, lon: float, heading: float) -> Path:
    """100 s: 20 s at rest, to 15 m/s, a 30 deg turn; MEMS IMU at 50 Hz, GNSS 1 Hz."""
    sc = {"name": name, "start": {"time": 0.0, "lat": lat, "lon": lon, "height": 50.0, "heading": heading},
          "imu": {"rate": 50, "sensor": "mems"},
          "gnss": {"rate": 1, "pos_noise": [1.5, 1.5, 3.0], "vel_noise": 0.05},
          "segments": [{"type": "rest", "duration": 20}, {"type": "accelerate", "speed": 15, "duration": 10},
                       {"type": "cruise", "duration": 20}, {"type": "turn", "angle": 30, "duration": 10,
                                                            "bank": "none"},
                       {"type": "cruise", "duration": 40}]}
    path = d / f"{name}.yaml"
    path.write_text(yaml.safe_dump(sc))
    return path


# antimeridian: from 179.995 E heading 80 deg, the drive crosses 180 after about 45 s; near the poles the
# same drive at +-89.85 deg, where a longitude turns by degrees per second of driving
EDGES = {"antimeridian": (30.0, 179.995, 80.0), "north": (89.85, 179.995, 80.0), "south": (-89.85, -179.995, 100.0)}


@pytest.fixture(scope="module")
def edge(tmp_path_factory):
    d = tmp_path_factory.mktemp("edges")
    out = {}
    for name, (lat, lon, heading) in EDGES.items():
        sc = _scenario(d, name, lat, lon, heading)
        for kind, extra in (("perfect", ["--perfect"]), ("noisy", ["--seed", "5"])):
            rc, lines = sins(["simulate", sc, "-o", d / f"{name}_{kind}", "-q", *extra])
            assert rc == 0, lines
        out[name] = d
    return d


def _lon_ok(lon_deg):
    lon_deg = np.asarray(lon_deg)
    return bool(np.all((lon_deg >= -180.0) & (lon_deg < 180.0)))


def _read_any(path: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(lat deg, lon deg, height) of an output of any format (TUM: from its ENU about the origin line)."""
    suffix = path.suffix
    if suffix in (".csv", ".parquet"):
        t = read_trajectory(path)
        return np.degrees(t.lat), np.degrees(t.lon), t.height
    if suffix == ".mcap":
        t = read_trajectory_mcap(path)
        return np.degrees(t.lat), np.degrees(t.lon), t.height
    if suffix == ".geojson":
        _, lat, lon, h = read_geojson(path)
        return lat, lon, h
    if suffix == ".kml":
        return read_kml(path)
    _, enu, _, origin = read_tum(path)
    from sinscli.nav.earth import local_enu_to_lla
    lat, lon, h = local_enu_to_lla(enu, *origin)
    return np.degrees(lat), np.degrees(lon), h


@pytest.mark.parametrize("where", sorted(EDGES))
def test_plain_navigation_at_the_edges_matches_the_exact_truth_in_every_format(edge, tmp_path, where):
    """Perfect sensors: every format's track within 1e-6 m of the exact truth (the navigator's level: the
    drive's own errors are 1e-7 m), longitudes in [-180, 180), and the compare report across the edge."""
    src = edge / f"{where}_perfect"
    truth = read_trajectory(src / "truth.csv")
    assert _lon_ok(np.degrees(truth.lon)) and np.abs(np.degrees(truth.lat)).max() < 90.0
    if where == "antimeridian":                              # the truth itself crosses 180
        assert np.degrees(truth.lon).max() > 179.99 and np.degrees(truth.lon).min() < -179.99
    for fmt in FORMATS:
        out = tmp_path / f"nav.{fmt}"
        rc, lines = sins(["navigate", src / "imu.csv", "--init", src / "init.yaml", "-o", out, "-q"])
        assert rc == 0, (fmt, lines)
        lat, lon, h = _read_any(out)
        assert _lon_ok(lon) and np.all(np.abs(lat) <= 90.0), fmt
        n = len(lat)
        assert n == len(truth) or fmt == "tum" and n == len(truth)
        err = position_error_enu(truth.lat, truth.lon, truth.height, np.radians(lat), np.radians(lon), h)
        limit = 2e-3 if fmt == "tum" else 1e-6         # TUM: positions in a local ENU plane, printed exactly;
        assert np.abs(err[:, :2]).max() < limit, (fmt, np.abs(err).max())   # back through ECEF to lat/lon
    rc, lines = sins(["compare", "--truth", src / "truth.csv", tmp_path / "nav.csv", "-o", tmp_path / "rep", "-q"])
    assert rc == 0, lines
    rows = {r[0]: float(r[-1]) for r in (ln.split(",") for ln in (tmp_path / "rep" / "errors.csv").read_text()
                                         .splitlines()[1:])}
    assert max(abs(rows["max_pos_E"]), abs(rows["max_pos_N"])) < 1e-6, rows


def test_geojson_is_cut_at_the_antimeridian_and_reads_back_whole(edge, tmp_path):
    """RFC 7946 3.1.9: a line crossing the antimeridian is a MultiLineString cut there (no 360 deg jump
    within a part); read back, the parts are the whole track, equal to the CSV's longitudes."""
    src = edge / "antimeridian_perfect"
    for fmt in ("csv", "geojson"):
        rc, lines = sins(["navigate", src / "imu.csv", "--init", src / "init.yaml", "-o", tmp_path / f"n.{fmt}", "-q"])
        assert rc == 0, lines
    geom = json.loads((tmp_path / "n.geojson").read_text())["features"][0]["geometry"]
    assert geom["type"] == "MultiLineString" and len(geom["coordinates"]) == 2
    for part in geom["coordinates"]:
        lon = np.array([p[0] for p in part])
        assert np.abs(np.diff(lon)).max() < 1e-3                    # no jump inside a part
    _, lat, lon, _ = read_geojson(tmp_path / "n.geojson")
    csv = np.genfromtxt(tmp_path / "n.csv", delimiter=",", names=True)
    assert np.array_equal(lon, csv["lon"]) and np.array_equal(lat, csv["lat"])


@pytest.mark.parametrize("where", sorted(EDGES))
def test_fused_navigation_at_the_edges_uses_every_fix(edge, tmp_path, where):
    """Fused: every GNSS fix accepted (across the antimeridian 9 good fixes were rejected and the residual
    RMS was 7.77e+06 m), the residual RMS at the fixes' noise (1.5 m per axis: ~2 m horizontal), the track
    within a few metres of the exact truth, in every format."""
    src = edge / f"{where}_noisy"
    truth = read_trajectory(src / "truth.csv")
    for fmt in FORMATS:
        out = tmp_path / f"fused.{fmt}"
        rc, lines = sins(["navigate", src / "imu.csv", "--gnss", src / "gnss.csv", "--init", src / "init.yaml",
                          "--sensor", "mems", "-o", out])
        assert rc == 0, (fmt, lines)
        fixes = next(ln for ln in lines if ln.startswith("sins: fusion: GNSS fixes"))
        assert fixes == "sins: fusion: GNSS fixes 100 of 100 used", fixes        # none rejected
        summary = next(ln for ln in lines if "residual RMS against the fixes" in ln)
        rms = float(summary.split("residual RMS against the fixes outside outages ")[1].split(" m horizontal")[0])
        assert rms < 3.0, summary
        lat, lon, h = _read_any(out)
        assert _lon_ok(lon) and np.all(np.abs(lat) <= 90.0), fmt
        if fmt in ("csv", "parquet", "mcap", "geojson", "kml"):
            err = position_error_enu(truth.lat, truth.lon, truth.height, np.radians(lat), np.radians(lon), h)
            assert np.hypot(err[:, 0], err[:, 1]).max() < 4.0, (fmt, np.abs(err).max())


@pytest.mark.parametrize("lat", ["90.0", "-90.0", "89.995", "-89.9950001"])
def test_gnss_fixes_at_a_pole_are_refused_like_the_init(edge, tmp_path, lat):
    """The GNSS reader applies the init reader's near-pole rule (0.01 deg), naming line and column: before,
    fixes at 90 N gave exit 0 with 5,368 rows beyond 90 deg and longitudes up to 1341 deg."""
    src = edge / "north_noisy"
    lines = (src / "gnss.csv").read_text().splitlines()
    cells = lines[5].split(",")
    cells[1] = lat
    lines[5] = ",".join(cells)
    (tmp_path / "gnss.csv").write_text("\n".join(lines) + "\n")
    refused(["navigate", src / "imu.csv", "--gnss", tmp_path / "gnss.csv", "--init", src / "init.yaml",
             "-o", tmp_path / "f.csv"], "gnss.csv: line 6, column 'lat'", "within 0.01 deg of a pole",
            "leave them out")
    assert not (tmp_path / "f.csv").exists()
    init = yaml.safe_load((src / "init.yaml").read_text())
    init["lat"] = float(lat)
    (tmp_path / "init.yaml").write_text(yaml.safe_dump(init))
    refused(["navigate", src / "imu.csv", "--init", tmp_path / "init.yaml", "-o", tmp_path / "n.csv"],
            "within 0.01 deg of a pole", "--frame launch-inertial")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["gnss.csv", "init.yaml"]


def test_navsatfix_at_a_pole_is_refused(tmp_path):
    from sinscli.io import ros
    t = np.arange(0.0, 12.0)
    gnss = {"time": t, "lat": np.full(12, 89.5), "lon": np.full(12, 10.0), "height": np.full(12, 5.0),
            "cov": np.tile([1.0, 0, 0, 0, 1.0, 0, 0, 0, 4.0], (12, 1))}
    gnss["lat"][7] = 89.999
    ros.write_log(tmp_path / "g.bag", gnss=gnss)
    refused(["convert", tmp_path / "g.bag", "-o", tmp_path / "out"], "g.bag: topic /fix: message 7, column 'latitude'",
            "within 0.01 deg of a pole")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["g.bag"]


def _traj(lat_deg, lon_deg):
    n = len(lat_deg)
    return Trajectory(np.arange(n, dtype=float), np.radians(lat_deg), np.radians(lon_deg), np.full(n, 10.0),
                      np.zeros((n, 3)), np.tile(np.eye(3), (n, 1, 1)), source="test")


@pytest.mark.parametrize("fmt", FORMATS)
def test_every_writer_refuses_a_latitude_beyond_90(tmp_path, fmt):
    """The writers' guard (atomic.output_lon_lat): a track over a pole (in the ENU mechanization a latitude
    past 90 deg) is refused naming output, row, epoch and column, and nothing is written."""
    path = tmp_path / f"t.{fmt}"
    with pytest.raises(NonFiniteOutput, match=r"t\.\w+: internal consistency check: row 3 \(time 2\.0 s\), "
                                              r"column 'lat': 90\.0+\d* deg is outside \[-90, 90\]"):
        write_trajectory(path, _traj([89.9, 89.99, 90.00001, 89.99], [0.0, 1.0, 2.0, 3.0]))
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("fmt", FORMATS)
def test_every_writer_wraps_longitudes(tmp_path, fmt):
    """A navigator's longitude runs on past 180 (and past -180): every writer emits [-180, 180)."""
    lon = np.array([179.9, 180.0, 180.1, 359.0, 540.5, -180.2, -190.0])
    path = tmp_path / f"t.{fmt}"
    write_trajectory(path, _traj(np.full(lon.size, 45.0), lon))
    expect = np.array([179.9, -180.0, -179.9, -1.0, -179.5, 179.8, 170.0])
    if fmt == "tum":                                       # TUM holds one longitude: its origin line's
        origin = read_tum(path)[3]
        assert np.degrees(origin[1]) == pytest.approx(179.9, abs=1e-12)
        return
    _, back, _ = _read_any(path)
    assert np.abs(dlon(back, expect, 180.0)).max() < 1e-9 and _lon_ok(back), (fmt, back)


def test_wrap_and_difference_of_longitudes():
    """wrap_lon leaves values in range bit for bit and folds the rest; dlon is the plain difference inside
    a half turn and the short way across the antimeridian, for arrays, scalars and in the kernels."""
    x = np.array([-180.0, -179.99999999999997, 0.1, 179.99999999999997])
    assert np.array_equal(wrap_lon(x, 180.0), x)
    assert wrap_lon(180.0, 180.0) == -180.0 and wrap_lon(540.0, 180.0) == -180.0 and wrap_lon(-181.0, 180.0) == 179.0
    assert wrap_lon(math.pi) == -math.pi
    a, b = math.radians(179.9999), math.radians(-179.9999)
    assert dlon(a, b) == pytest.approx(math.radians(-0.0002), abs=1e-15)
    assert dlon_nb(a, b) == dlon(a, b) and dlon_nb(b, a) == -dlon(a, b)
    rng = np.random.default_rng(1)
    p, q = rng.uniform(-3, 3, 1000), rng.uniform(-3, 3, 1000)
    inside = np.abs(p - q) <= math.pi
    assert np.array_equal(dlon(p, q)[inside], (p - q)[inside])             # nothing changes off the edge
    assert np.abs(dlon(p, q)).max() <= math.pi
    assert np.allclose(np.cos(dlon(p, q)), np.cos(p - q), atol=1e-15)


def test_local_enu_offsets_across_the_antimeridian():
    """ENU offsets about an origin are through ECEF: 0.0002 deg of longitude across 180 at 30 N is 19.3 m east."""
    e = lla_to_local_enu(np.radians([30.0]), np.radians([-179.9999]), np.array([0.0]), math.radians(30.0),
                         math.radians(179.9999), 0.0)
    from sinscli.nav.earth import radii_py
    _, rn = radii_py(math.sin(math.radians(30.0)))
    east = rn * math.cos(math.radians(30.0)) * math.radians(0.0002)
    assert e[0, 0] == pytest.approx(east, rel=1e-6)
    # north: the parallel curves away from the east axis, east^2 tan(lat) / (2 RN) = 1.7e-5 m
    assert e[0, 1] == pytest.approx(east ** 2 * math.tan(math.radians(30.0)) / (2 * rn), rel=1e-3)
