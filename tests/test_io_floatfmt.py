"""The compiled shortest round-trip formatter (sinscli/io/floatfmt.py, Ryu; issue 21) against two outside
oracles: Python's ``repr`` (David Gay's shortest digits) with ``float()`` reading the text back, and pyarrow's
CSV writer (double-conversion ``ToShortest``), whose bytes the trajectory files had before (the regression
golden, tests/test_nav_regression.py, checks whole files)."""
import numpy as np
import pyarrow as pa
import pyarrow.csv as pacsv
import pytest

from sinscli.io.floatfmt import MAX_CHARS, format_floats, format_rows, row_bytes
from test_io_csv_roundtrip import HARD

# the boundaries of the layout (decimal for decimal exponents -6 .. 9), powers of two and ten around them,
# the extremes, the even/odd significand cases where the interval's bounds are in or out
EDGES = ([10.0 ** k for k in range(-8, 24)] + [1.5 * 10.0 ** k for k in range(-8, 24)] + [2.0 ** k for k in range(-1074, 1024, 7)]
         + [9.999999999999999e-7, 1e-6, 9.99999999999999e9, 9999999999.999998, 1e10, 5e-324, 1e-323, 4.9406564584124654e-324,
            2.2250738585072009e-308, 1.7976931348623157e308, 0.30000000000000004, 9007199254740991.0, 9007199254740992.0,
            1.0e22, 1.0e23, 5.0e-324 * 3, 2.0 ** -1022 * (1 - 2.0 ** -52)])


def _arrow_text(x: np.ndarray) -> bytes:
    t = pa.Table.from_arrays([pa.Array.from_buffers(pa.float64(), len(x), [None, pa.py_buffer(np.ascontiguousarray(x))])],
                             names=["x"])
    sink = pa.BufferOutputStream()
    pacsv.write_csv(t, sink, write_options=pacsv.WriteOptions(include_header=False, quoting_style="none"))
    return sink.getvalue().to_pybytes()


def _repr_digits(x: float) -> tuple[str, int]:
    """Python's shortest digits of |x| and the decimal exponent of the first: 1234.5 -> ("12345", 3)."""
    m, _, e = repr(abs(x)).partition("e")
    whole, _, frac = m.partition(".")
    digits = (whole + frac).lstrip("0")
    exp = (len(whole) - 1 if whole.strip("0") else -(len(frac) - len(frac.lstrip("0"))) - 1) + (int(e) if e else 0)
    return digits.rstrip("0") or "0", exp


def _text_digits(text: str) -> tuple[str, int]:
    m, _, e = text.lstrip("-").partition("e")
    whole, _, frac = m.partition(".")
    digits = (whole + frac).lstrip("0")
    exp = (len(whole) - 1 if whole.strip("0") else -(len(frac) - len(frac.lstrip("0"))) - 1) + (int(e) if e else 0)
    return digits.rstrip("0") or "0", exp


def _check_against_oracles(x: np.ndarray):
    texts = format_floats(x).decode().split("\n")[:-1]
    assert len(texts) == len(x)
    back = np.array([float(t) for t in texts])
    assert np.array_equal(back.view(np.uint64), x.view(np.uint64))          # bit for bit, -0.0 and subnormals
    for t, v in zip(texts, x.tolist()):
        if v != 0.0:
            assert _text_digits(t) == _repr_digits(v), (t, repr(v))        # the same shortest digits as repr
    assert format_floats(x) == _arrow_text(x)                               # the writer's layout, byte for byte


def test_hard_cases_and_layout_edges():
    x = np.array(HARD + [-v for v in HARD] + EDGES + [-v for v in EDGES])
    _check_against_oracles(x)


def test_layout_examples():
    x = np.array([1e-7, 1e-6, 1.5e-5, 123.0, 12.5, 1e9, 1e10, 1.5e10, -0.0, 0.0, 5e-324, 1e21, 2.0 ** 53 + 2])
    assert format_floats(x).decode().split() == ["1e-7", "0.000001", "0.000015", "123", "12.5", "1000000000",
                                                 "1e+10", "1.5e+10", "-0", "0", "5e-324", "1e+21",
                                                 "9.007199254740994e+15"]


def test_a_million_random_bit_patterns():
    rng = np.random.default_rng(21)
    x = rng.integers(0, 2 ** 64 - 1, 1_000_000, dtype=np.uint64, endpoint=True).view(np.float64)
    x = x[np.isfinite(x)]
    assert len(x) > 990_000
    _check_against_oracles(x)


def test_random_integers_decimals_and_near_ties():
    """Values whose shortest form is short (integers, 1-6 decimals) and 17-digit values next to them:
    where a formatter that does not pick the closest of several shortest candidates goes wrong."""
    rng = np.random.default_rng(5)
    ints = rng.integers(-10 ** 15, 10 ** 15, 100_000).astype(np.float64)
    dec = np.round(rng.uniform(-1e4, 1e4, 100_000), rng.integers(0, 7, 100_000)[0])
    near = np.nextafter(dec, np.inf)
    _check_against_oracles(np.concatenate([ints, dec, near, ints / 1024.0]))


def test_rows_with_suffix_and_the_buffer_bound():
    rows = np.array([[1.0, -1.7976931348623157e308], [-2.2250738585072014e-308, 0.5]])
    suffix = np.frombuffer(b",flu", np.uint8)
    out = np.zeros(rows.shape[0] * row_bytes(2, 4), np.uint8)
    n = format_rows(rows, suffix, out)
    assert out[:n].tobytes() == b"1,-1.7976931348623157e+308,flu\n-2.2250738585072014e-308,0.5,flu\n"
    # the longest text of any float64 (sign, 17 digits, point, e-308) is MAX_CHARS: the buffer bound holds
    assert len(format_floats(np.array([-2.2250738585072014e-308])).strip()) == MAX_CHARS == 24
