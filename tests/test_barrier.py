"""The relaxed barrier of order k = 2 (paper eq. 27): C2 at the switch point, the 1/delta^2 curvature of the
relaxed branch, derivatives consistent with the value, and argument checking."""

from __future__ import annotations

import numpy as np
import pytest

from hsddp_gym.planners.optimizer.barrier import relaxed_barrier

DELTAS = (1e-3, 0.05, 0.2, 0.4, 1.0, 3.0)


def _rel(a, b) -> float:
    a, b = float(a), float(b)
    return abs(a - b) / max(abs(a), abs(b), 1e-300)


@pytest.mark.parametrize("delta", DELTAS)
def test_value_slope_curvature_continuous_at_delta(delta):
    """Left (relaxed branch, c = delta exactly and just below) and right (log branch, just above) limits agree."""
    t = 1e-10 * delta
    c = np.array([delta - t, delta, delta + t])
    value, slope, curvature = relaxed_barrier(c, delta)
    # c = delta itself is in the relaxed branch (the log branch is c > delta)
    assert value[1] == pytest.approx(-np.log(delta), rel=1e-14, abs=1e-14)
    assert slope[1] == pytest.approx(-1.0 / delta, rel=1e-14)
    assert curvature[1] == pytest.approx(1.0 / delta ** 2, rel=1e-14)
    for left in (0, 1):
        # the value's relative difference uses max(|value|, 1): -log(delta) vanishes at delta = 1
        assert abs(value[left] - value[2]) <= 1e-6 * max(1.0, abs(value[2]))
        assert _rel(slope[left], slope[2]) <= 1e-6
        assert _rel(curvature[left], curvature[2]) <= 1e-6
    # and the analytic one-sided limits of eq. 27 (k = 2) are -log(delta), -1/delta, 1/delta^2 on both sides
    assert _rel(-1.0 / (delta + t), slope[2]) <= 1e-14
    assert _rel(1.0 / (delta + t) ** 2, curvature[2]) <= 1e-14


@pytest.mark.parametrize("delta", DELTAS)
def test_relaxed_branch_matches_eq27_and_has_curvature_one_over_delta_squared(delta, rng):
    c = np.concatenate([delta * rng.uniform(-20.0, 1.0, 50), [delta, 0.0, -delta, 2.0 * delta - 5.0]])
    c = c[c <= delta]
    value, slope, curvature = relaxed_barrier(c, delta)
    np.testing.assert_allclose(curvature, 1.0 / delta ** 2, rtol=1e-14)
    expected = 0.5 * (((c - 2.0 * delta) / delta) ** 2 - 1.0) - np.log(delta)
    np.testing.assert_allclose(value, expected, rtol=1e-13, atol=1e-13)
    np.testing.assert_allclose(slope, (c - 2.0 * delta) / delta ** 2, rtol=1e-13, atol=1e-13 / delta)
    # the relaxed barrier extends -log over the whole real line: finite everywhere, decreasing below delta
    assert np.all(np.isfinite(value)) and np.all(slope < 0)


@pytest.mark.parametrize("delta", DELTAS)
def test_log_branch_is_minus_log(delta, rng):
    c = delta * (1.0 + rng.uniform(1e-6, 50.0, 50))
    value, slope, curvature = relaxed_barrier(c, delta)
    np.testing.assert_allclose(value, -np.log(c), rtol=1e-14, atol=1e-14)
    np.testing.assert_allclose(slope, -1.0 / c, rtol=1e-14)
    np.testing.assert_allclose(curvature, 1.0 / c ** 2, rtol=1e-14)


@pytest.mark.parametrize("delta", DELTAS)
def test_slope_and_curvature_match_finite_differences(delta, rng):
    """Random points on both sides of delta (and straddling it): central differences of the value give the
    slope, central differences of the slope give the curvature."""
    c = np.concatenate([delta * rng.uniform(-5.0, 1.0, 40), delta * rng.uniform(1.0, 30.0, 40),
                        delta * (1.0 + rng.uniform(-1e-3, 1e-3, 10))])
    # a step relative to the local scale: the log branch varies on the scale of c itself
    h = 1e-5 * np.maximum(np.minimum(np.abs(c), delta), 1e-3 * delta)
    value, slope, curvature = relaxed_barrier(c, delta)
    vp, sp, _ = relaxed_barrier(c + h, delta)
    vm, sm, _ = relaxed_barrier(c - h, delta)
    fd_slope = (vp - vm) / (2.0 * h)
    fd_curv = (sp - sm) / (2.0 * h)
    np.testing.assert_allclose(fd_slope, slope, rtol=1e-6, atol=1e-9 / delta)
    np.testing.assert_allclose(fd_curv, curvature, rtol=1e-6, atol=1e-9 / delta ** 2)


def test_broadcasting_and_per_element_delta(rng):
    c = rng.uniform(-1.0, 2.0, (3, 5))
    deltas = rng.uniform(0.1, 0.6, (1, 5))
    value, slope, curvature = relaxed_barrier(c, deltas)
    assert value.shape == slope.shape == curvature.shape == c.shape
    for j in range(5):
        v, s, k = relaxed_barrier(c[:, j], float(deltas[0, j]))
        np.testing.assert_array_equal(value[:, j], v)
        np.testing.assert_array_equal(slope[:, j], s)
        np.testing.assert_array_equal(curvature[:, j], k)
    # scalar input gives 0-d outputs
    v0, s0, k0 = relaxed_barrier(0.5, 0.2)
    assert np.ndim(v0) == np.ndim(s0) == np.ndim(k0) == 0
    assert float(v0) == pytest.approx(-np.log(0.5))


@pytest.mark.parametrize("delta", [0.0, -0.1, -1.0, np.nan, np.inf, -np.inf, np.array([0.2, 0.0]),
                                   np.array([0.2, np.nan])])
def test_bad_delta_raises(delta):
    with pytest.raises(ValueError, match="delta"):
        relaxed_barrier(np.array([0.1, 0.5]), delta)


def test_far_inside_the_constraint_no_overflow_far_outside_an_infinite_barrier():
    """The relaxed branch is not evaluated where it is not used: c = 1e200 gives -log(c) without an overflow
    warning; c = -1e200 (a huge violation) gives an infinite value, which the solver rejects."""
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        value, slope, curvature = relaxed_barrier(np.array([1e200, 2.0]), 0.2)
    np.testing.assert_allclose(value, -np.log([1e200, 2.0]))
    with np.errstate(over="ignore"):
        assert relaxed_barrier(np.array([-1e200]), 0.2)[0][0] == np.inf


@pytest.mark.parametrize("delta", DELTAS)
def test_compiled_kernels_are_bit_identical_to_relaxed_barrier(delta, rng):
    """The objective's fused kernels (:mod:`hsddp_gym.planners.optimizer.kernels`) give, bit for bit, what the
    NumPy expressions of the objective give with :func:`relaxed_barrier` -- on both branches, exactly at delta,
    far inside and far outside (overflows), at +-inf and nan."""
    from hsddp_gym.planners.optimizer import kernels

    umax, eps, n = 33.0, 7e-4, 40
    special = np.array([delta, umax - delta, umax + delta, 0.0, -0.0, 1e200, -1e200, np.inf, -np.inf, np.nan,
                        np.nextafter(delta, 0.0), np.nextafter(delta, 1.0)])
    U = np.concatenate([umax * rng.uniform(-1.2, 1.2, 4 * n - special.size), special]).reshape(n, 4)
    c = np.concatenate([delta * rng.uniform(-30.0, 30.0, 6 * n - special.size), special]).reshape(n, 6)
    mask = (rng.uniform(size=(n, 6)) > 0.3).astype(float)
    with np.errstate(all="ignore"):
        v_up, d_up, dd_up = relaxed_barrier(umax - U, delta)
        v_lo, d_lo, dd_lo = relaxed_barrier(umax + U, delta)
        v_f, d_f, dd_f = relaxed_barrier(c, delta)
        l_u, l_uu = rng.normal(size=(n, 4)), rng.normal(size=(n, 4, 4))
        want_l_u = l_u + eps * (d_lo - d_up)
        want_l_uu = l_uu.copy()
        want_l_uu[:, range(4), range(4)] += eps * (dd_up + dd_lo)
        kernels.torque_barrier_derivatives(U, umax, delta, eps, l_u, l_uu)
        _assert_same_bits(l_u, want_l_u)
        _assert_same_bits(l_uu, want_l_uu)
        dc, ddc = np.empty((n, 6)), np.empty((n, 6))
        kernels.force_barrier_derivatives(c, delta, eps, mask, dc, ddc)
        _assert_same_bits(dc, d_f * (eps * mask))
        _assert_same_bits(ddc, dd_f * (eps * mask))
        safe = np.empty((n, 14))
        kernels.barrier_safe(U, c, umax, delta, delta, safe)
        np.log(safe, out=safe)
        b_up, b_lo, b_f = np.empty((n, 4)), np.empty((n, 4)), np.empty((n, 6))
        log_delta = float(np.log(delta))
        kernels.barrier_values(U, c, umax, delta, delta, log_delta, log_delta, safe, mask, b_up, b_lo, b_f)
        _assert_same_bits(b_up, v_up)
        _assert_same_bits(b_lo, v_lo)
        _assert_same_bits(b_f, v_f * mask)


def _assert_same_bits(actual, expected):
    """Equal as IEEE bit patterns (signed zeros and nan payloads included)."""
    actual, expected = np.ascontiguousarray(actual), np.ascontiguousarray(expected)
    assert actual.shape == expected.shape
    np.testing.assert_array_equal(actual.view(np.uint64), expected.view(np.uint64))
