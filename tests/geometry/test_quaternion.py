"""Properties of the numpy quaternion module, with scipy as an independent reference."""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays
from scipy.spatial.transform import Rotation

from robot_retarget.geometry import quaternion as quat

FloatArray = npt.NDArray[np.float64]

EXAMPLES = settings(max_examples=150, deadline=None)


def unit_quaternions() -> st.SearchStrategy[FloatArray]:
    raw = arrays(np.float64, 4, elements=st.floats(-1.0, 1.0))
    return raw.filter(lambda q: bool(np.linalg.norm(q) > 0.1)).map(quat.normalize)


def vectors(min_norm: float = 0.1) -> st.SearchStrategy[FloatArray]:
    raw = arrays(np.float64, 3, elements=st.floats(-10.0, 10.0))
    return raw.filter(lambda v: bool(np.linalg.norm(v) > min_norm))


def same_rotation(a: FloatArray, b: FloatArray, atol: float = 1e-12) -> bool:
    """q and −q are the same rotation: compare |a · b| with 1."""
    return bool(np.all(np.abs(np.abs(np.sum(a * b, axis=-1)) - 1.0) < atol))


def to_scipy(q: FloatArray) -> Rotation:
    return Rotation.from_quat(np.roll(q, -1, axis=-1))  # scipy stores (x, y, z, w)


# --- matrices --------------------------------------------------------------------------------


@EXAMPLES
@given(unit_quaternions())
def test_matrix_is_a_rotation(q: FloatArray) -> None:
    m = quat.to_matrix(q)
    np.testing.assert_allclose(m @ m.T, np.eye(3), atol=1e-12)
    assert np.linalg.det(m) == pytest.approx(1.0, abs=1e-12)


@EXAMPLES
@given(unit_quaternions())
def test_matrix_round_trip(q: FloatArray) -> None:
    back = quat.from_matrix(quat.to_matrix(q))
    assert back[0] >= 0.0
    assert same_rotation(back, q)
    np.testing.assert_allclose(quat.to_matrix(back), quat.to_matrix(q), atol=1e-12)


def test_matrix_round_trip_batch_with_half_turns(random_quats: FloatArray) -> None:
    m = quat.to_matrix(random_quats)
    back = quat.from_matrix(m)
    np.testing.assert_allclose(np.linalg.norm(back, axis=-1), 1.0, atol=1e-14)
    assert same_rotation(back, random_quats)
    assert np.all(back[..., 0] >= 0.0)


def test_matrix_matches_scipy(random_quats: FloatArray) -> None:
    np.testing.assert_allclose(
        quat.to_matrix(random_quats), to_scipy(random_quats).as_matrix(), atol=1e-12
    )
    m = Rotation.random(300, random_state=5).as_matrix()
    ref = np.roll(Rotation.from_matrix(m).as_quat(), 1, axis=-1)
    assert same_rotation(quat.from_matrix(m), ref)


def test_batch_shapes_broadcast() -> None:
    q = quat.normalize(np.random.default_rng(1).normal(size=(2, 3, 4)))
    assert quat.mul(q, q[0]).shape == (2, 3, 4)
    assert quat.rotate(q, np.ones(3)).shape == (2, 3, 3)
    assert quat.to_matrix(q).shape == (2, 3, 3, 3)
    assert quat.from_matrix(quat.to_matrix(q)).shape == (2, 3, 4)
    assert quat.identity((2, 5)).shape == (2, 5, 4)


# --- products, inverse, rotating vectors ------------------------------------------------------


@EXAMPLES
@given(unit_quaternions(), unit_quaternions(), unit_quaternions())
def test_product_is_associative(a: FloatArray, b: FloatArray, c: FloatArray) -> None:
    np.testing.assert_allclose(quat.mul(quat.mul(a, b), c), quat.mul(a, quat.mul(b, c)), atol=1e-14)


@EXAMPLES
@given(unit_quaternions(), unit_quaternions())
def test_product_agrees_with_matrix_product(a: FloatArray, b: FloatArray) -> None:
    np.testing.assert_allclose(
        quat.to_matrix(quat.mul(a, b)), quat.to_matrix(a) @ quat.to_matrix(b), atol=1e-13
    )


def test_product_is_hamilton() -> None:
    # i ⊗ j = k and j ⊗ i = −k in Hamilton's convention (JPL would give the opposite).
    i, j, k = np.eye(4)[1], np.eye(4)[2], np.eye(4)[3]
    np.testing.assert_array_equal(quat.mul(i, j), k)
    np.testing.assert_array_equal(quat.mul(j, i), -k)
    np.testing.assert_array_equal(quat.mul(i, i), [-1.0, 0.0, 0.0, 0.0])


@EXAMPLES
@given(unit_quaternions())
def test_conjugate_is_inverse(q: FloatArray) -> None:
    np.testing.assert_allclose(quat.mul(q, quat.conjugate(q)), quat.identity(), atol=1e-14)
    np.testing.assert_allclose(quat.mul(quat.conjugate(q), q), quat.identity(), atol=1e-14)
    np.testing.assert_allclose(quat.to_matrix(quat.conjugate(q)), quat.to_matrix(q).T, atol=1e-14)


@EXAMPLES
@given(unit_quaternions(), vectors(min_norm=0.0))
def test_rotate_is_matrix_times_vector(q: FloatArray, v: FloatArray) -> None:
    np.testing.assert_allclose(quat.rotate(q, v), quat.to_matrix(q) @ v, atol=1e-12)
    assert np.linalg.norm(quat.rotate(q, v)) == pytest.approx(np.linalg.norm(v), abs=1e-12)


def test_rotate_matches_scipy(random_quats: FloatArray, rng: np.random.Generator) -> None:
    v = rng.normal(size=(len(random_quats), 3))
    np.testing.assert_allclose(
        quat.rotate(random_quats, v), to_scipy(random_quats).apply(v), atol=1e-12
    )


def test_rotate_quarter_turn_about_z() -> None:
    q = quat.from_axis_angle([0.0, 0.0, 1.0], np.pi / 2)
    np.testing.assert_allclose(quat.rotate(q, [1.0, 0.0, 0.0]), [0.0, 1.0, 0.0], atol=1e-15)


# --- normalisation and signs ------------------------------------------------------------------


@EXAMPLES
@given(
    arrays(np.float64, 4, elements=st.floats(-1e3, 1e3)).filter(
        lambda q: bool(np.linalg.norm(q) > 1e-6)
    )
)
def test_normalize_gives_unit_norm(q: FloatArray) -> None:
    n = quat.normalize(q)
    assert np.linalg.norm(n) == pytest.approx(1.0, abs=1e-14)
    assert same_rotation(n, q / np.linalg.norm(q))


@pytest.mark.parametrize(
    "bad", [np.zeros(4), np.array([1e-14, 0.0, 0.0, 0.0]), np.array([np.nan, 1.0, 0.0, 0.0])]
)
def test_normalize_of_zero_or_nan_raises(bad: FloatArray) -> None:
    with pytest.raises(ValueError, match="normalise"):
        quat.normalize(bad)


def test_normalize_raises_if_any_row_is_zero() -> None:
    with pytest.raises(ValueError, match="zero"):
        quat.normalize(np.array([[1.0, 0.0, 0.0, 0.0], [0.0, 0.0, 0.0, 0.0]]))


@EXAMPLES
@given(unit_quaternions())
def test_canonical_sign(q: FloatArray) -> None:
    c = quat.canonical_sign(q)
    assert c[0] >= 0.0
    assert np.array_equal(c, q) or np.array_equal(c, -q)
    assert np.array_equal(quat.canonical_sign(-q), c) or q[0] == 0.0


@settings(max_examples=100, deadline=None)
@given(
    arrays(np.float64, (12, 4), elements=st.floats(-1.0, 1.0)).filter(
        lambda q: bool(np.all(np.linalg.norm(q, axis=-1) > 0.1))
    ),
    arrays(np.bool_, 12),
)
def test_make_continuous(q: FloatArray, flip: npt.NDArray[np.bool_]) -> None:
    q = quat.normalize(q)
    q = np.where(flip[:, None], -q, q)
    out = quat.make_continuous(q)
    assert np.all(np.sum(out[1:] * out[:-1], axis=-1) >= 0.0)
    np.testing.assert_array_equal(out[0], q[0])  # the first frame is the reference
    assert np.all((out == q).all(-1) | (out == -q).all(-1))  # only whole-sign flips


def test_make_continuous_along_another_axis(rng: np.random.Generator) -> None:
    # A smooth motion (3 joints, 50 frames, time on axis 1) with random sign flips.
    angles = np.linspace(0.0, 3.0, 50)
    smooth = quat.from_axis_angle(rng.normal(size=(3, 1, 3)), angles[None, :] * [[1.0], [2], [3]])
    signs = rng.choice([-1.0, 1.0], size=(3, 50, 1))
    signs[:, 0] = 1.0
    out = quat.make_continuous(smooth * signs, axis=1)
    np.testing.assert_allclose(out, smooth, atol=1e-15)


def test_make_continuous_single_frame_unchanged() -> None:
    q = np.array([[-1.0, 0.0, 0.0, 0.0]])
    np.testing.assert_array_equal(quat.make_continuous(q), q)


# --- axis-angle and rotation vectors ----------------------------------------------------------

ANGLES_NEAR_ZERO_AND_PI = [0.0, 1e-15, 1e-12, 1e-9, 1e-7, 1e-6, 1e-3, np.pi - 1e-6, np.pi - 1e-9]


@EXAMPLES
@given(vectors(), st.floats(1e-6, np.pi - 1e-6))
def test_axis_angle_round_trip(axis: FloatArray, angle: float) -> None:
    q = quat.from_axis_angle(axis, angle)
    assert np.linalg.norm(q) == pytest.approx(1.0, abs=1e-14)
    back_axis, back_angle = quat.to_axis_angle(q)
    assert back_angle == pytest.approx(angle, abs=1e-12)
    np.testing.assert_allclose(back_axis, axis / np.linalg.norm(axis), atol=1e-9)


@pytest.mark.parametrize("angle", ANGLES_NEAR_ZERO_AND_PI)
def test_axis_angle_near_zero_and_pi(angle: float) -> None:
    axis = np.array([0.3, -0.5, 0.8]) / np.linalg.norm([0.3, -0.5, 0.8])
    back_axis, back_angle = quat.to_axis_angle(quat.from_axis_angle(axis, angle))
    assert back_angle == pytest.approx(angle, rel=1e-9, abs=1e-15)
    if angle > 1e-12:
        np.testing.assert_allclose(back_axis, axis, atol=1e-6)
    else:  # no rotation: the documented fallback axis
        np.testing.assert_array_equal(back_axis, [1.0, 0.0, 0.0])


def test_to_axis_angle_of_negated_quaternion_is_unchanged() -> None:
    q = quat.from_axis_angle([0.0, 1.0, 0.0], 2.5)
    axis, angle = quat.to_axis_angle(-q)
    np.testing.assert_allclose(axis, [0.0, 1.0, 0.0], atol=1e-15)
    assert angle == pytest.approx(2.5, abs=1e-14)  # [0, π], not 2π − 2.5


def test_from_axis_angle_of_zero_axis_raises() -> None:
    with pytest.raises(ValueError, match="axis"):
        quat.from_axis_angle(np.zeros(3), 1.0)


@EXAMPLES
@given(vectors(min_norm=0.0).filter(lambda v: bool(np.linalg.norm(v) < np.pi - 1e-6)))
def test_rotation_vector_round_trip(rv: FloatArray) -> None:
    q = quat.from_rotation_vector(rv)
    assert np.linalg.norm(q) == pytest.approx(1.0, abs=1e-14)
    np.testing.assert_allclose(quat.to_rotation_vector(q), rv, atol=1e-12)


@EXAMPLES
@given(unit_quaternions())
def test_quaternion_to_rotation_vector_and_back(q: FloatArray) -> None:
    rv = quat.to_rotation_vector(q)
    assert np.linalg.norm(rv) <= np.pi + 1e-12
    assert same_rotation(quat.from_rotation_vector(rv), q)


@pytest.mark.parametrize("angle", ANGLES_NEAR_ZERO_AND_PI)
def test_rotation_vector_precise_near_zero_and_pi(angle: float) -> None:
    axis = np.array([2.0, -1.0, 2.0]) / 3.0
    rv = quat.to_rotation_vector(quat.from_rotation_vector(axis * angle))
    # Below 1e-12 the axis falls back to x̂; the vector is still within 1e-12 of the input.
    atol = 1e-12 if angle <= 1e-12 else 0.0
    np.testing.assert_allclose(rv, axis * angle, rtol=1e-9, atol=atol)


def test_rotation_vectors_match_scipy(random_quats: FloatArray) -> None:
    rv = quat.to_rotation_vector(random_quats)
    ref = to_scipy(random_quats).as_rotvec()
    # Half-turns have two valid vectors (±axis · π); compare rotations there.
    half_turn = np.linalg.norm(ref, axis=-1) > np.pi - 1e-6
    np.testing.assert_allclose(rv[~half_turn], ref[~half_turn], atol=1e-9)
    q_ref = np.roll(Rotation.from_rotvec(ref).as_quat(), 1, axis=-1)
    assert same_rotation(quat.from_rotation_vector(ref), q_ref)


# --- distances and interpolation --------------------------------------------------------------


@EXAMPLES
@given(unit_quaternions(), unit_quaternions())
def test_angle_between_is_a_symmetric_sign_blind_distance(a: FloatArray, b: FloatArray) -> None:
    d = quat.angle_between(a, b)
    assert 0.0 <= d <= np.pi
    assert quat.angle_between(b, a) == pytest.approx(d, abs=1e-12)
    assert quat.angle_between(a, -b) == pytest.approx(d, abs=1e-12)
    ref = (to_scipy(a).inv() * to_scipy(b)).magnitude()
    assert d == pytest.approx(ref, abs=1e-7)
    assert quat.angle_between(a, a) < 1e-7


@pytest.mark.parametrize("tiny", [1e-14, 1e-11, 1e-9, 1e-7])
def test_angle_between_precise_for_tiny_angles(tiny: float) -> None:
    a = quat.normalize([0.4, -0.2, 0.7, 0.5])
    b = quat.mul(a, quat.from_axis_angle([1.0, 2.0, -2.0], tiny))
    assert quat.angle_between(a, b) == pytest.approx(tiny, rel=1e-6)


@EXAMPLES
@given(unit_quaternions(), unit_quaternions())
def test_slerp_endpoints(a: FloatArray, b: FloatArray) -> None:
    np.testing.assert_allclose(quat.slerp(a, b, 0.0), a, atol=1e-12)
    assert same_rotation(quat.slerp(a, b, 1.0), b)


@EXAMPLES
@given(unit_quaternions(), unit_quaternions(), st.floats(0.0, 1.0))
def test_slerp_constant_speed_on_the_shortest_arc(a: FloatArray, b: FloatArray, t: float) -> None:
    total = quat.angle_between(a, b)
    qt = quat.slerp(a, b, t)
    assert np.linalg.norm(qt) == pytest.approx(1.0, abs=1e-14)
    assert quat.angle_between(a, qt) == pytest.approx(t * total, abs=1e-7)
    assert quat.angle_between(qt, b) == pytest.approx((1.0 - t) * total, abs=1e-7)
    # −b is the same rotation: same path.
    assert same_rotation(quat.slerp(a, -b, t), qt, atol=1e-10)


def test_slerp_of_nearly_equal_rotations_is_linear() -> None:
    a = quat.normalize([0.5, 0.5, -0.5, 0.5])
    b = quat.mul(a, quat.from_axis_angle([0.0, 0.0, 1.0], 1e-12))
    mid = quat.slerp(a, b, np.array([0.0, 0.5, 1.0]))
    assert np.all(np.isfinite(mid))
    np.testing.assert_allclose(mid[1], quat.normalize(a + b), atol=1e-15)


def test_slerp_broadcasts_t() -> None:
    a = quat.identity()
    b = quat.from_axis_angle([0.0, 1.0, 0.0], 1.0)
    out = quat.slerp(a, b, np.linspace(0.0, 1.0, 11))
    np.testing.assert_allclose(quat.angle_between(a, out), np.linspace(0.0, 1.0, 11), atol=1e-12)


# --- swing-twist ------------------------------------------------------------------------------


@EXAMPLES
@given(unit_quaternions(), vectors())
def test_swing_twist_recomposes(q: FloatArray, axis: FloatArray) -> None:
    swing, twist = quat.swing_twist(q, axis)
    u = axis / np.linalg.norm(axis)
    np.testing.assert_allclose(quat.mul(swing, twist), q, atol=1e-12)
    assert np.linalg.norm(twist) == pytest.approx(1.0, abs=1e-12)
    # Twist is a rotation about the axis; swing has no component about it.
    np.testing.assert_allclose(np.cross(twist[1:], u), 0.0, atol=1e-12)
    assert np.dot(swing[1:], u) == pytest.approx(0.0, abs=1e-12)
    # Swing moves the axis exactly as q does (twist leaves it alone).
    np.testing.assert_allclose(quat.rotate(swing, u), quat.rotate(q, u), atol=1e-12)


@EXAMPLES
@given(vectors(), st.floats(-np.pi + 1e-9, np.pi), unit_quaternions())
def test_twist_angle_recovers_the_twist(axis: FloatArray, angle: float, s: FloatArray) -> None:
    u = axis / np.linalg.norm(axis)
    # A swing about an axis perpendicular to u, then a known twist about u.
    perp = np.cross(u, s[1:])
    if np.linalg.norm(perp) < 1e-3:
        perp = np.cross(u, [1.0, 0.0, 0.0] if abs(u[0]) < 0.9 else [0.0, 1.0, 0.0])
    # Keep clear of a half-turn swing, where the twist is undefined (ill-conditioned near it).
    swing_angle = min(2.0 * np.arctan2(np.linalg.norm(s[1:]), abs(s[0])), 3.0)
    swing = quat.from_axis_angle(perp, swing_angle)
    q = quat.mul(swing, quat.from_axis_angle(u, angle))
    # Compared on the circle: a twist of π may come back as −π + rounding (the same rotation).
    for sign in (1.0, -1.0):
        got = float(quat.twist_angle(sign * q, axis))
        assert math.remainder(got - angle, 2.0 * math.pi) == pytest.approx(0.0, abs=1e-9)


def test_twist_angle_range_is_half_open() -> None:
    assert quat.twist_angle(quat.from_axis_angle([0, 0, 1.0], np.pi), [0, 0, 1.0]) == np.pi
    assert quat.twist_angle(quat.from_axis_angle([0, 0, 1.0], -np.pi), [0, 0, 1.0]) == np.pi
    assert quat.twist_angle(quat.from_axis_angle([0, 0, 1.0], -1.0), [0, 0, 2.0]) == (
        pytest.approx(-1.0, abs=1e-15)
    )


def test_swing_twist_degenerate_half_turn() -> None:
    q = quat.from_axis_angle([1.0, 0.0, 0.0], np.pi)  # half-turn perpendicular to z
    q = np.array([0.0, *q[1:]])  # exactly, without cos(π/2) rounding
    swing, twist = quat.swing_twist(q, [0.0, 0.0, 1.0])
    np.testing.assert_array_equal(twist, quat.identity())
    np.testing.assert_allclose(swing, q, atol=1e-15)


def test_from_two_vectors_is_exact_away_from_antiparallel() -> None:
    rng = np.random.default_rng(5)
    a, b = rng.normal(size=(2, 5000, 3))
    keep = np.sum(a * b, axis=-1) / np.linalg.norm(a, axis=-1) / np.linalg.norm(b, axis=-1) > -0.99
    q = quat.from_two_vectors(a[keep], b[keep])
    unit_b = b[keep] / np.linalg.norm(b[keep], axis=-1, keepdims=True)
    unit_a = a[keep] / np.linalg.norm(a[keep], axis=-1, keepdims=True)
    np.testing.assert_allclose(quat.rotate(q, unit_a), unit_b, atol=1e-14)


def test_swing_twist_of_zero_axis_raises() -> None:
    with pytest.raises(ValueError, match="non-zero"):
        quat.swing_twist(quat.identity(), np.zeros(3))


# --- from_two_vectors -------------------------------------------------------------------------


@EXAMPLES
@given(vectors(), vectors())
def test_from_two_vectors_is_the_shortest_arc(a: FloatArray, b: FloatArray) -> None:
    q = quat.from_two_vectors(a, b)
    ua, ub = a / np.linalg.norm(a), b / np.linalg.norm(b)
    assert np.linalg.norm(q) == pytest.approx(1.0, abs=1e-14)
    # 3e-8, not machine precision: the shortest arc between nearly opposite directions has an
    # ill-conditioned axis (see from_two_vectors); elsewhere the error is ~1e-16.
    np.testing.assert_allclose(quat.rotate(q, ua), ub, atol=3e-8)
    angle = np.arctan2(np.linalg.norm(np.cross(ua, ub)), np.dot(ua, ub))
    assert quat.to_axis_angle(q)[1] == pytest.approx(angle, abs=1e-7)


@pytest.mark.parametrize(
    "a", [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, -3.0], [0.3, -0.4, 0.5], [0.95, 0.1, 0.0]]
)
def test_from_two_vectors_opposite_and_parallel(a: list[float]) -> None:
    va = np.array(a)
    ua = va / np.linalg.norm(va)
    half = quat.from_two_vectors(va, -2.0 * va)
    np.testing.assert_allclose(quat.rotate(half, ua), -ua, atol=1e-12)
    assert quat.to_axis_angle(half)[1] == pytest.approx(np.pi, abs=1e-12)
    np.testing.assert_allclose(quat.from_two_vectors(va, 5.0 * va), quat.identity(), atol=1e-15)


def test_from_two_vectors_of_zero_vector_raises() -> None:
    with pytest.raises(ValueError, match="non-zero"):
        quat.from_two_vectors(np.zeros(3), [1.0, 0.0, 0.0])
