"""The CSV writer (sinscli.io.csvcore.CsvTableWriter): every float reads back to the identical float64
(docs/formats.md), in the shortest form, through the threaded, streamed path; the pandas-free column view."""
import math
import sys

import numpy as np
import pyarrow as pa
import pytest

from sinscli.io import csvcore
from sinscli.io.atomic import NonFiniteOutput, atomic_path

HARD = [0.0, -0.0, 5e-324, -5e-324, 2.225073858507201e-308, 2.2250738585072014e-308, 1e-300, -1e-320,
        1.7976931348623157e308, -1.7976931348623157e308, 1.0, -3.0, 2.0 ** 53, 2.0 ** 53 + 2, 9007199254740993.0,
        1e15, 1e16, 1e17, 1e21, 1e22, 1e23, 123456789012345678.0, 0.1, 0.2, 0.1 + 0.2, 1 / 3, 2 / 3,
        math.pi, math.e, 1.0000000000000002, 0.9999999999999999, 1e-7, 1.5e-5, 123.456, 4.35, 0.3,
        5e-310, 8.41e21, 2.9802322387695312e-08, 1.2345678901234567, 9.999999999999999e22, 4.940656458412e-324]


def _write(path, columns, rows_per_chunk, threads):
    names = list(columns)
    n = len(next(iter(columns.values())))
    with atomic_path(path) as tmp:
        with csvcore.CsvTableWriter(tmp, names, threads=threads) as w:
            for a in range(0, n, rows_per_chunk):
                w.write({c: v[a:a + rows_per_chunk] for c, v in columns.items()})
            w.close()


def _python_shortest(x: float) -> str:
    """Digits of Python's repr (David Gay's shortest round-trip), without sign, point and exponent."""
    r = repr(abs(float(x)))
    mant = r.split("e")[0].replace(".", "").lstrip("0").rstrip("0")
    return mant or "0"


def _digits(text: str) -> str:
    mant = text.lstrip("-").lower().split("e")[0].replace(".", "").lstrip("0").rstrip("0")
    return mant or "0"


@pytest.mark.parametrize("threads", [1, 3])
def test_hard_values_round_trip_shortest(tmp_path, threads):
    x = np.array(HARD)
    out = tmp_path / "hard.csv"
    _write(out, {"time": np.arange(len(x), dtype=float), "x": x, "neg": -x}, 7, threads)
    lines = out.read_text().splitlines()
    assert lines[0] == "time,x,neg"
    assert len(lines) == len(x) + 1
    for k, line in enumerate(lines[1:]):
        t, a, b = line.split(",")
        assert float(t) == k
        for text, want in ((a, x[k]), (b, -x[k])):
            got = float(text)
            assert got == want and math.copysign(1.0, got) == math.copysign(1.0, want), (text, want)
            assert len(_digits(text)) == len(_python_shortest(want)), (text, repr(want))
    back = csvcore.read_numeric_columns(out, {"x": "x", "neg": "neg"})
    assert back["x"].view(np.int64).tolist() == x.view(np.int64).tolist()      # bit for bit, -0.0 too
    assert back["neg"].view(np.int64).tolist() == (-x).view(np.int64).tolist()


def test_random_bit_patterns_round_trip_through_threads_and_chunks(tmp_path):
    """200,000 finite float64 from random bit patterns (every exponent, subnormals) and 17-digit values,
    written in uneven chunks over the slice boundary, read back bit for bit in order."""
    rng = np.random.default_rng(14)
    bits = rng.integers(0, 2 ** 63, 100_000, dtype=np.uint64) | (rng.integers(0, 2, 100_000, dtype=np.uint64) << 63)
    x = bits.view(np.float64)
    x = x[np.isfinite(x)]
    y = rng.standard_normal(len(x)) * 10.0 ** rng.integers(-12, 12, len(x))
    n = len(x)
    old = csvcore.FORMAT_ROWS
    csvcore.FORMAT_ROWS = 4096                 # many slices in flight, so that their order is tested
    try:
        out = tmp_path / "rand.csv"
        _write(out, {"time": np.arange(n, dtype=float), "x": x, "y": y}, 30_001, 3)
    finally:
        csvcore.FORMAT_ROWS = old
    back = csvcore.read_numeric_columns(out, {"time": "time", "x": "x", "y": "y"})
    assert np.array_equal(back["time"], np.arange(n))
    assert np.array_equal(back["x"].view(np.int64), x.view(np.int64))
    assert np.array_equal(back["y"].view(np.int64), y.view(np.int64))
    sample = rng.choice(n, 2000, replace=False)        # shortest, checked against Python's repr
    lines = out.read_text().splitlines()
    for k in sample:
        text = lines[k + 1].split(",")[1]
        assert len(_digits(text)) == len(_python_shortest(float(x[k]))), (text, repr(float(x[k])))


def test_non_finite_refused_naming_row_and_no_file(tmp_path):
    out = tmp_path / "bad.csv"
    x = np.arange(10.0)
    x[7] = np.nan
    with pytest.raises(NonFiniteOutput, match=r"bad\.csv: .*row 8 .*column 'x'"):
        _write(out, {"time": np.arange(10.0), "x": x}, 4, 2)
    assert list(tmp_path.iterdir()) == []


def test_float_column_views_without_pandas_and_is_writable():
    chunked = pa.chunked_array([pa.array([1.0, -0.0]), pa.array([5e-324]).slice(0)])
    a = csvcore.float_column(chunked)
    assert a.tolist() == [1.0, -0.0, 5e-324] and math.copysign(1, a[1]) < 0
    sliced = csvcore.float_column(pa.array([1.0, 2.0, 3.0, 4.0]).slice(1, 2))
    assert sliced.tolist() == [2.0, 3.0] and sliced.flags.writeable
    assert csvcore.float_column(pa.array([1, 2], pa.int32())).tolist() == [1.0, 2.0]


def test_navigate_reader_does_not_import_pandas(tmp_path):
    """pyarrow's to_numpy imports pandas (0.15-0.3 s of every run); the IMU reader must not."""
    import subprocess
    p = tmp_path / "imu.csv"
    p.write_text("time,dtheta_x,dtheta_y,dtheta_z,dvel_x,dvel_y,dvel_z\n0.01,0,0,0,0,0,0.098\n0.02,0,0,0,0,0,0.098\n")
    code = ("import sys; from sinscli.io.readers import iter_imu; from sinscli import config; "
            f"list(iter_imu({str(p)!r}, config.load_config(None))); print('pandas' in sys.modules)")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert r.stdout.strip() == "False"


@pytest.mark.parametrize("bad_line", [3, 700, 1999])
def test_streamed_blocks_read_ahead_keep_order_and_name_a_late_bad_cell(tmp_path, bad_line):
    """The IMU reader parses the next block on a thread: blocks come in order and complete, and a bad
    cell in any block is refused with its line and column (not an exception from the thread)."""
    from sinscli.errors import SinsError
    from sinscli.io.imu_csv import iter_imu_csv
    n = 2000
    t = 0.01 * np.arange(1, n + 1)
    rows = ["time,dtheta_x,dtheta_y,dtheta_z,dvel_x,dvel_y,dvel_z"]
    rows += [f"{float(t[k])!r},1e-5,2e-5,3e-5,0.001,0.002,{0.098 + 1e-6 * k!r}" for k in range(n)]
    path = tmp_path / "imu.csv"
    path.write_text("\n".join(rows) + "\n")
    blocks = list(iter_imu_csv(path, block_bytes=4096))          # ~60 rows per block
    assert len(blocks) > 20
    assert np.array_equal(np.concatenate([b.time for b in blocks]), t)
    bad = rows.copy()
    bad[bad_line - 1] = bad[bad_line - 1].replace(",0.002,", ",0.0o2,")
    path.write_text("\n".join(bad) + "\n")
    with pytest.raises(SinsError) as err:
        list(iter_imu_csv(path, block_bytes=4096))
    msg = str(err.value)
    assert f"line {bad_line}" in msg and "dvel_y" in msg and "0.0o2" in msg, msg
