"""``nav.earth.enu_offset``, the one small-angle (lat, lon, h) -> ENU offset, against the exact ECEF route."""
import numpy as np

from sinscli.nav.earth import enu_offset, lla_to_local_enu, radii_py


def test_small_angle_offset_against_the_exact_local_enu():
    rng = np.random.default_rng(7)
    lat0, lon0, h0 = np.radians(47.3), np.radians(8.5), 420.0
    for scale in (1.0, 100.0, 1000.0):
        d = rng.normal(size=(200, 3)) * scale                    # metres E, N, U about the reference
        rm, rn = radii_py(np.sin(lat0))
        lat = lat0 + d[:, 1] / (rm + h0)
        lon = lon0 + d[:, 0] / ((rn + h0) * np.cos(lat0))
        h = h0 + d[:, 2]
        exact = lla_to_local_enu(lat, lon, h, lat0, lon0, h0)
        got = enu_offset(lat, lon, h, lat0, lon0, h0)
        err = np.abs(got - exact).max()
        # second order in the offset: |d|^2 / R with R ~ 6.4e6 m (plus the radii taken at the point)
        assert err < 3.0 * (3.0 * scale) ** 2 / 6.3e6 + 1e-9, (scale, err)
        assert err > 0.0 or scale == 1.0


def test_offset_wraps_the_longitude_and_broadcasts():
    lat = np.radians(10.0)
    e = enu_offset(lat, np.radians(-179.9999), 5.0, lat, np.radians(179.9999), 2.0)
    rm, rn = radii_py(np.sin(lat))
    assert np.isclose(e[0], np.radians(0.0002) * (rn + 5.0) * np.cos(lat), rtol=1e-9)
    assert e[1] == 0.0 and e[2] == 3.0
    assert enu_offset(np.zeros(4), np.zeros(4), np.zeros(4), 0.0, 0.0, 0.0).shape == (4, 3)
