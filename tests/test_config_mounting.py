"""``imu.mounting`` through scipy.spatial.transform.Rotation (config.mounting_matrix, mounting_angles) against the
written-out product ``Rz(yaw) Ry(pitch) Rx(roll)``, and the round trip, gimbal lock included."""
import math

import numpy as np
import pytest

from sinscli.config import mounting_angles, mounting_matrix


def _product(roll, pitch, yaw):
    r, p, y = map(math.radians, (roll, pitch, yaw))
    rx = np.array([[1, 0, 0], [0, math.cos(r), -math.sin(r)], [0, math.sin(r), math.cos(r)]])
    ry = np.array([[math.cos(p), 0, math.sin(p)], [0, 1, 0], [-math.sin(p), 0, math.cos(p)]])
    rz = np.array([[math.cos(y), -math.sin(y), 0], [math.sin(y), math.cos(y), 0], [0, 0, 1]])
    return rz @ ry @ rx


def test_matrix_is_the_zyx_product():
    rng = np.random.default_rng(3)
    for roll, pitch, yaw in rng.uniform(-360, 360, (500, 3)):
        m = mounting_matrix({"roll": roll, "pitch": pitch, "yaw": yaw})
        assert np.abs(m - _product(roll, pitch, yaw)).max() < 2e-15
    # the Husky's mounting: v_body = C v_sensor turns the sensor's +y (up at rest) into body +z
    assert np.allclose(mounting_matrix({"roll": 90}) @ [0, 1, 0], [0, 0, 1], atol=1e-15)
    assert np.array_equal(mounting_matrix(None), np.eye(3))


@pytest.mark.parametrize("ang", [(10, 20, 30), (-170, 89.5, 45), (0, -60, -179), (90, 0, 0)])
def test_angles_invert_the_matrix(ang):
    got = mounting_angles(_product(*ang))
    assert np.allclose([got["roll"], got["pitch"], got["yaw"]], ang, atol=1e-6)


def test_gimbal_lock_folds_the_roll_into_the_yaw():
    for pitch in (90.0, -90.0):
        c = _product(30.0, pitch, 10.0)
        got = mounting_angles(c)
        assert got["roll"] == 0.0 and got["pitch"] == pitch
        assert np.abs(mounting_matrix(got) - c).max() < 1e-8              # the same rotation (6-decimal angles)
