"""Taylor jets: derivatives against closed forms and finite differences; earth formulas on jets."""
import numpy as np
import pytest

from sinscli.nav.earth import gravity_py, radii_py
from sinscli.nav.rotation import FLU, euler_to_dcm
from sinscli.sim.jets import Jet, axis_rotation, polynomial, stack
from sinscli.sim.segments import C_FLU_TO_RFU

T = np.linspace(0.1, 1.3, 7)


def tj(t=T, order=2):
    return Jet.time(t, order)


@pytest.mark.parametrize("f, d1, d2", [
    (lambda t: np.sin(3 * t), lambda t: 3 * np.cos(3 * t), lambda t: -9 * np.sin(3 * t)),
    (lambda t: np.cos(t * t), lambda t: -2 * t * np.sin(t * t),
     lambda t: -2 * np.sin(t * t) - 4 * t * t * np.cos(t * t)),
    (lambda t: np.tan(t), lambda t: 1 / np.cos(t) ** 2, lambda t: 2 * np.tan(t) / np.cos(t) ** 2),
    (lambda t: np.arctan(2 * t), lambda t: 2 / (1 + 4 * t * t), lambda t: -16 * t / (1 + 4 * t * t) ** 2),
    (lambda t: np.sqrt(1 + t), lambda t: 0.5 / np.sqrt(1 + t), lambda t: -0.25 * (1 + t) ** -1.5),
    (lambda t: np.exp(-t), lambda t: -np.exp(-t), lambda t: np.exp(-t)),
    (lambda t: np.log(t), lambda t: 1 / t, lambda t: -1 / t ** 2),
    (lambda t: 1.0 / (2.0 + t), lambda t: -1 / (2 + t) ** 2, lambda t: 2 / (2 + t) ** 3),
    (lambda t: (1 + t) ** 2.5, lambda t: 2.5 * (1 + t) ** 1.5, lambda t: 3.75 * (1 + t) ** 0.5),
    (lambda t: t * t * t - 2.0 * t, lambda t: 3 * t * t - 2, lambda t: 6 * t),
    (lambda t: np.square(np.sin(t)), lambda t: np.sin(2 * t), lambda t: 2 * np.cos(2 * t)),
    (lambda t: np.arctan2(np.sin(t), 2.0 * np.cos(t)),
     lambda t: 2 / (np.cos(t) ** 2 * 4 + np.sin(t) ** 2),
     lambda t: 2 * (8 - 2) * np.sin(t) * np.cos(t) / (4 * np.cos(t) ** 2 + np.sin(t) ** 2) ** 2),
])
def test_jet_derivatives_match_closed_forms(f, d1, d2):
    j = f(tj())
    assert np.allclose(j.v, f(T), rtol=1e-14, atol=0)
    assert np.allclose(j.d1, d1(T), rtol=1e-13, atol=1e-15)
    assert np.allclose(j.d2, d2(T), rtol=1e-12, atol=1e-14)


def _fd(f, t, h=1e-3):
    """Fourth-order central differences of a plain function: (f', f'')."""
    fp = (-f(t + 2 * h) + 8 * f(t + h) - 8 * f(t - h) + f(t - 2 * h)) / (12 * h)
    fpp = (-f(t + 2 * h) + 16 * f(t + h) - 30 * f(t) + 16 * f(t - h) - f(t - 2 * h)) / (12 * h * h)
    return fp, fpp


def test_composite_against_finite_differences():
    def f(t):
        return np.arctan2(np.exp(np.sin(t)) * (1 + t * t), np.sqrt(3 + np.cos(2 * t))) / (1 + t)
    j = f(tj())
    fp, fpp = _fd(f, T)
    assert np.allclose(j.d1, fp, rtol=1e-9, atol=1e-11)
    assert np.allclose(j.d2, fpp, rtol=1e-6, atol=1e-8)


def test_earth_formulas_run_on_jets_unchanged():
    lat = lambda t: 0.3 + 0.2 * np.sin(t)          # noqa: E731
    h = lambda t: 100.0 + 5e4 * t * t               # noqa: E731
    rm_j, rn_j = radii_py(np.sin(lat(tj())))
    g_j = gravity_py(np.sin(lat(tj())), h(tj()))
    for jet, plain in ((rm_j, lambda t: radii_py(np.sin(lat(t)))[0]),
                       (rn_j, lambda t: radii_py(np.sin(lat(t)))[1]),
                       (g_j, lambda t: gravity_py(np.sin(lat(t)), h(t)))):
        assert np.allclose(jet.v, plain(T), rtol=1e-15)
        fp, fpp = _fd(plain, T)
        assert np.allclose(jet.d1, fp, rtol=1e-7, atol=1e-12 * np.abs(jet.v).max())
        assert np.allclose(jet.d2, fpp, rtol=1e-4, atol=1e-9 * np.abs(jet.v).max())
    # closed form of dg/dh at constant latitude: -3.0876910891e-6 + 4.3977311e-9 s^2 + 2 * 7.211e-13 h
    s = np.sin(0.5)
    g = gravity_py(s, Jet.time(T * 1e4, 1))
    assert np.allclose(g.d1, -3.0876910891e-6 + 4.3977311e-9 * s * s + 2 * 7.211e-13 * T * 1e4, rtol=1e-14)


def test_matrix_jets_and_rotation_chain_match_euler_to_dcm():
    t = tj()
    hdg, pit, rol = 0.7 + 2 * t, -0.4 + t * t, 3.0 * np.sin(t)
    c = axis_rotation(2, -hdg) @ axis_rotation(0, pit) @ axis_rotation(1, rol) @ C_FLU_TO_RFU
    for k in range(T.size):
        ref = euler_to_dcm(rol.v[k], pit.v[k], hdg.v[k], FLU)
        assert np.abs(c.v[k] - ref).max() < 1e-15
    # derivative of the product against finite differences of euler_to_dcm
    h = 1e-4
    for k in range(T.size):
        def plain(tt):
            return euler_to_dcm(3.0 * np.sin(tt), -0.4 + tt * tt, 0.7 + 2 * tt, FLU)
        t0 = T[k]
        fd = (-plain(t0 + 2 * h) + 8 * plain(t0 + h) - 8 * plain(t0 - h) + plain(t0 - 2 * h)) / (12 * h)
        assert np.abs(c.d1[k] - fd).max() < 1e-10
        # C^T dC/dt is skew-symmetric (the angular rate)
        w = c.v[k].T @ c.d1[k]
        assert np.abs(w + w.T).max() < 1e-14


def test_polynomial_and_stack():
    coeffs = [1.0, -2.0, 0.5, 3.0]
    u = (tj() - 0.1) / 2.0
    p = polynomial(coeffs, u)
    uv = (T - 0.1) / 2.0
    assert np.allclose(p.v, 1 - 2 * uv + 0.5 * uv ** 2 + 3 * uv ** 3, rtol=1e-15)
    assert np.allclose(p.d1, (-2 + uv + 9 * uv ** 2) / 2.0, rtol=1e-14)
    assert np.allclose(p.d2, (1 + 18 * uv) / 4.0, rtol=1e-14)
    v = stack([np.sin(tj()), 2.0, tj()], axis=-1)
    assert v.shape == (T.size, 3)
    assert np.array_equal(v.d1[:, 1], np.zeros(T.size)) and np.array_equal(v.d1[:, 2], np.ones(T.size))
