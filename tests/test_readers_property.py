"""Property tests (hypothesis) of the CSV and YAML readers: any text either reads to finite arrays with the
promised invariants, or raises one :class:`SinsError` line that names the file."""
from __future__ import annotations

import math
import string
import tempfile
from pathlib import Path

import numpy as np
import yaml
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st

from sinscli.config import DEFAULTS, Limits, load_config
from sinscli.errors import SinsError
from sinscli.io.gnss_csv import read_gnss_csv
from sinscli.io.imu_csv import read_imu_csv
from sinscli.io.init_state import INIT_KEYS, read_init
from sinscli.io.trajectory import BASE_COLUMNS, DCM_COLUMNS, read_trajectory

SETTINGS = settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
LIM = Limits()

# ------------------------------------------------------------------ text generators

NUMBERS = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True).map(repr),
    st.floats(-1e4, 1e4).map(lambda x: f"{x:.6g}"),
    st.integers(-10 ** 30, 10 ** 30).map(str),
    st.sampled_from(["", "nan", "inf", "-inf", "1e400", "-1e400", "abc", " 1 ", "1,5", '"2"', "0x1f", "1e-400"]))
CELL_TEXT = st.text(alphabet=string.printable + "\xe9\u00a0\ufeff", max_size=12)


def _csv(names, rows) -> str:
    return "\n".join([",".join(names)] + [",".join(r) for r in rows]) + "\n"


def structured_csv(columns):
    """A header drawn from the reader's column names (and some junk), rows of numbers and junk."""
    names = st.lists(st.one_of(st.sampled_from(columns), CELL_TEXT), min_size=1, max_size=len(columns) + 2)
    return st.builds(lambda n, rows: _csv(n, rows), names,
                     st.lists(st.lists(st.one_of(NUMBERS, CELL_TEXT), min_size=0, max_size=len(columns) + 2),
                              max_size=8))


def plausible_csv(columns, time_step=0.01):
    """The reader's own header with mostly numeric rows around valid values: exercises the success path."""
    def build(rows, junk):
        lines = []
        for k, r in enumerate(rows):
            cells = [repr(round(time_step * (k + 1), 6))] + [repr(v) for v in r]
            lines.append(cells)
        for (i, j), v in junk:
            if lines:
                lines[i % len(lines)][j % len(columns)] = v
        return _csv(columns, lines)
    row = st.lists(st.floats(-1.0, 1.0), min_size=len(columns) - 1, max_size=len(columns) - 1)
    return st.builds(build, st.lists(row, min_size=0, max_size=12),
                     st.lists(st.tuples(st.tuples(st.integers(0, 20), st.integers(0, 20)), NUMBERS), max_size=2))


def any_text():
    return st.one_of(st.text(max_size=300), st.binary(max_size=300))


def _write(data, suffix: str) -> Path:
    d = Path(tempfile.mkdtemp(prefix="sins-prop-"))
    p = d / f"input{suffix}"
    if isinstance(data, str):
        p.write_text(data, encoding="utf-8")
    else:
        p.write_bytes(data)
    return p


def read_or_refuse(reader, path: Path):
    """``reader(path)``, or None after checking that its refusal is one line naming the file."""
    try:
        out = reader(path)
    except SinsError as exc:
        event("refused")
        msg = str(exc)
        assert "\n" not in msg and path.name in msg, msg
        assert "np.float64(" not in msg and len(msg) <= 480, msg
        return None
    event("read")
    return out


# ------------------------------------------------------------------ CSV readers

IMU_INC = ["time", "dtheta_x", "dtheta_y", "dtheta_z", "dvel_x", "dvel_y", "dvel_z"]
IMU_RATE = ["time", "gyro_x", "gyro_y", "gyro_z", "accel_x", "accel_y", "accel_z"]


def _check_imu(path):
    imu = read_or_refuse(read_imu_csv, path)
    if imu is None:
        return
    assert len(imu) >= 1 and imu.dtheta_b.shape == (len(imu), 3) and imu.dvel_b.shape == (len(imu), 3)
    for a in (imu.time, imu.dtheta_b, imu.dvel_b):
        assert np.isfinite(a).all()
    assert np.all(np.diff(imu.time) > 0)
    assert np.abs(imu.time).max() <= LIM.time
    if imu.kind == "rates":
        dt = np.diff(np.concatenate([[imu.t0], imu.time]))
        assert np.all(dt > 0) and imu.t0 < imu.time[0]
        assert np.all(np.abs(imu.dtheta_b) <= LIM.rate * dt[:, None] * (1 + 1e-12))
        assert np.all(np.abs(imu.dvel_b) <= LIM.specific_force * dt[:, None] * (1 + 1e-12))


@SETTINGS
@given(st.one_of(structured_csv(IMU_INC), structured_csv(IMU_RATE), plausible_csv(IMU_INC),
                 plausible_csv(IMU_RATE), any_text()))
def test_imu_csv_reads_or_refuses(text):
    _check_imu(_write(text, ".csv"))


GNSS = ["time", "lat", "lon", "height", "vel_e", "vel_n", "vel_u", "std_e", "std_n", "std_u"]


@SETTINGS
@given(st.one_of(structured_csv(GNSS), plausible_csv(GNSS[:4], 1.0), plausible_csv(GNSS, 1.0), any_text()))
def test_gnss_csv_reads_or_refuses(text):
    path = _write(text, ".csv")
    g = read_or_refuse(read_gnss_csv, path)
    if g is None:
        return
    for a in (g.time, g.lat, g.lon, g.height):
        assert np.isfinite(a).all()
    assert np.all(np.diff(g.time) > 0)
    assert np.all(np.abs(g.lat) <= 90) and np.all(np.abs(g.lon) <= 360)
    assert np.all((g.height >= LIM.height_min) & (g.height <= LIM.height_max))
    if g.vel_n is not None:
        assert np.all(np.linalg.norm(g.vel_n, axis=1) <= LIM.speed)
    if g.std_pos is not None:
        assert np.all(g.std_pos >= 0)


TRAJ = BASE_COLUMNS + DCM_COLUMNS


def _rows_of_valid_trajectory(n, junk):
    """Valid rows (identity attitude at heading 0) with optional junk cells."""
    lines = []
    for k in range(n):
        row = [0.1 * k, 30.0, 114.0, 50.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0] + \
              [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]
        lines.append([repr(v) for v in row])
    for (i, j), v in junk:
        if lines:
            lines[i % len(lines)][j % len(TRAJ)] = v
    return _csv(TRAJ, lines)


@SETTINGS
@given(st.one_of(structured_csv(TRAJ),
                 st.builds(_rows_of_valid_trajectory, st.integers(0, 6),
                           st.lists(st.tuples(st.tuples(st.integers(0, 9), st.integers(0, 30)), NUMBERS), max_size=2)),
                 any_text()))
def test_trajectory_csv_reads_or_refuses(text):
    path = _write(text, ".csv")
    tr = read_or_refuse(read_trajectory, path)
    if tr is None:
        return
    for a in (tr.time, tr.lat, tr.lon, tr.height, tr.vel_n, tr.Cbn):
        assert np.isfinite(a).all()
    assert np.all(np.diff(tr.time) > 0)
    err = np.abs(np.einsum("nij,nkj->nik", tr.Cbn, tr.Cbn) - np.eye(3)).max() if len(tr) else 0.0
    assert err <= 2e-3
    assert np.all(np.abs(tr.lat) <= math.pi / 2)


# ------------------------------------------------------------------ YAML readers

SCALARS = st.one_of(st.none(), st.booleans(), st.integers(-2 ** 70, 2 ** 70), st.floats(allow_nan=True),
                    st.text(max_size=8))
VALUES = st.recursive(SCALARS, lambda inner: st.one_of(st.lists(inner, max_size=4),
                                                       st.dictionaries(st.text(max_size=6), inner, max_size=4)),
                      max_leaves=12)


def _init_docs():
    good = {"time": 0.0, "lat": 30.0, "lon": 114.0, "height": 50.0, "vel_e": 0.0, "vel_n": 0.0, "vel_u": 0.0,
            "roll": 0.0, "pitch": 0.0, "heading": 30.0}

    def edit(changes, drop):
        d = dict(good)
        d.update(changes)
        for k in drop:
            d.pop(k, None)
        return yaml.safe_dump(d)
    return st.one_of(
        st.builds(edit, st.dictionaries(st.sampled_from(INIT_KEYS + ["heding", "extra"]), VALUES, max_size=3),
                  st.lists(st.sampled_from(INIT_KEYS), max_size=2)),
        st.builds(edit, st.dictionaries(st.sampled_from(INIT_KEYS), st.floats(-200.0, 200.0), max_size=4),
                  st.just([])))


def yaml_docs(docs):
    """Documents of a YAML reader: its own structure edited, any YAML value, any text or bytes."""
    return st.one_of(docs, VALUES.map(yaml.safe_dump), any_text())


@SETTINGS
@given(yaml_docs(_init_docs()))
def test_init_yaml_reads_or_refuses(text):
    s = read_or_refuse(read_init, _write(text, ".yaml"))
    if s is None:
        return
    assert all(math.isfinite(x) for x in (s.time, s.lat, s.lon, s.height))
    assert np.isfinite(s.vel_n).all() and np.isfinite(s.Cbn).all()
    assert abs(s.lat) <= math.radians(89.99) and abs(s.time) <= LIM.time
    assert np.linalg.norm(s.vel_n) <= LIM.speed
    assert np.abs(s.Cbn @ s.Cbn.T - np.eye(3)).max() < 1e-12


def _config_docs():
    keys = [(sec, k) for sec, d in DEFAULTS.items() for k in d]

    def edit(changes):
        d: dict = {}
        for (sec, k), v in changes:
            d.setdefault(sec, {})[k] = v
        return yaml.safe_dump(d)
    return st.builds(edit, st.lists(st.tuples(st.sampled_from(keys), VALUES), max_size=3))


@SETTINGS
@given(yaml_docs(_config_docs()))
def test_config_yaml_loads_or_refuses(text):
    cfg = read_or_refuse(load_config, _write(text, ".yaml"))
    if cfg is None:
        return
    nav = cfg.navigation
    assert 1 <= nav.subsamples < 2 ** 31 and 1 <= nav.every < 2 ** 31
    assert 0 < nav.singularity_threshold < 1
    for v in vars(cfg.limits).values():
        assert math.isfinite(v)
    from sinscli.config import mounting_matrix
    m = mounting_matrix(cfg.imu.mounting)
    assert np.isfinite(m).all() and np.abs(m @ m.T - np.eye(3)).max() <= 1e-6



# ------------------------------------------------------------------ readers of the fusion inputs

ODOM = ["time", "vel_x", "vel_y", "vel_z", "std_x", "std_y", "std_z"]


@SETTINGS
@given(st.one_of(structured_csv(ODOM), plausible_csv(ODOM, 0.1), any_text()))
def test_body_velocity_csv_reads_or_refuses(text):
    from sinscli.io.readers import read_body_velocity
    bv = read_or_refuse(lambda p: read_body_velocity(p, load_config(None)), _write(text, ".csv"))
    if bv is None:
        return
    assert np.isfinite(bv.time).all() and np.isfinite(bv.vel_b).all() and np.all(np.diff(bv.time) > 0)
    assert np.abs(bv.time).max() <= LIM.time and np.linalg.norm(bv.vel_b, axis=1).max() <= LIM.speed
    assert bv.std is None or (np.isfinite(bv.std).all() and (bv.std > 0).all())


def _tum_docs():
    """TUM rows around valid poses (unit quaternions), with junk cells and an origin line."""
    def build(rows, junk, origin):
        lines = [f"# origin_lat_deg={origin[0]} origin_lon_deg={origin[1]} origin_height_m={origin[2]}"]
        for k, (p, q) in enumerate(rows):
            q = np.asarray(q) / (np.linalg.norm(q) or 1.0)
            lines.append(" ".join(repr(float(x)) for x in [0.1 * (k + 1), *p, *q]))
        for (i, j), v in junk:
            if len(lines) > 1:
                i = 1 + i % (len(lines) - 1)
                cells = lines[i].split()
                cells[j % 8] = v.replace(" ", "") or "x"
                lines[i] = " ".join(cells)
        return "\n".join(lines) + "\n"
    vec = st.lists(st.floats(-1e3, 1e3), min_size=3, max_size=3)
    quat = st.lists(st.floats(-1.0, 1.0), min_size=4, max_size=4)
    origin = st.tuples(*(st.one_of(st.floats(-100, 100).map(repr), NUMBERS) for _ in range(3)))
    return st.builds(build, st.lists(st.tuples(vec, quat), max_size=10),
                     st.lists(st.tuples(st.tuples(st.integers(0, 20), st.integers(0, 20)), NUMBERS), max_size=2),
                     origin)


@SETTINGS
@given(st.one_of(_tum_docs(), any_text()))
def test_tum_reads_or_refuses(text):
    from sinscli.io.tum import read_tum
    out = read_or_refuse(read_tum, _write(text, ".tum"))
    if out is None:
        return
    t, enu, q, origin = out
    assert np.isfinite(t).all() and np.isfinite(enu).all() and np.isfinite(q).all() and np.all(np.diff(t) > 0)
    assert np.abs(t).max() <= LIM.time and np.abs(enu).max() <= 1e8
    assert np.abs(np.linalg.norm(q, axis=1) - 1.0).max() <= 1e-3
    assert origin is None or (abs(math.degrees(origin[0])) <= 90 and math.isfinite(origin[2]))


def _fusion_docs():
    from sinscli.fusion.options import FUSION_DEFAULTS
    keys = [(k,) for k, v in FUSION_DEFAULTS.items() if not isinstance(v, dict)] + \
        [(k, j) for k, v in FUSION_DEFAULTS.items() if isinstance(v, dict) for j in v]

    def edit(changes):
        d: dict = {}
        for path, v in changes:
            node = d.setdefault("fusion", {})
            for k in path[:-1]:
                node = node.setdefault(k, {})
            node[path[-1]] = v
        return yaml.safe_dump(d)
    values = st.one_of(VALUES, st.floats(-1e12, 1e12), st.lists(st.floats(-1e12, 1e12), min_size=2, max_size=3))
    return st.builds(edit, st.lists(st.tuples(st.sampled_from(keys), values), max_size=3))


@SETTINGS
@given(yaml_docs(_fusion_docs()))
def test_fusion_section_loads_or_refuses(text):
    from sinscli.fusion.options import build_fusion_options
    path = _write(text, ".yaml")

    def read(p):
        cfg = load_config(p)
        return build_fusion_options(cfg.fusion, str(p), base_dir=p.parent)
    o = read_or_refuse(read, path)
    if o is None:
        return
    for name, v in vars(o).items():
        if isinstance(v, (float, np.ndarray)) and name != "base_dir":
            assert np.isfinite(v).all() and np.abs(v).max() <= 1e9, (name, v)
    for sigma in (o.gnss_pos_sigma, o.gnss_vel_sigma, o.init_pos_sigma, o.init_vel_sigma, o.init_att_sigma):
        assert (sigma > 0).all()
