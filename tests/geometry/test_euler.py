"""Euler angles in all 24 order strings: round trips, gimbal lock, composition and scipy."""

from __future__ import annotations

import itertools
import warnings

import numpy as np
import numpy.typing as npt
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays
from scipy.spatial.transform import Rotation

from robot_retarget.geometry import euler
from robot_retarget.geometry import quaternion as quat

FloatArray = npt.NDArray[np.float64]

_TAIT_BRYAN = ["".join(p) for p in itertools.permutations("XYZ")]
_PROPER = [a + b + a for a in "XYZ" for b in "XYZ" if a != b]
ORDERS = [o for base in _TAIT_BRYAN + _PROPER for o in (base, base.lower())]


def is_proper(order: str) -> bool:
    return order[0].lower() == order[2].lower()


def unit_quaternions() -> st.SearchStrategy[FloatArray]:
    raw = arrays(np.float64, 4, elements=st.floats(-1.0, 1.0))
    return raw.filter(lambda q: bool(np.linalg.norm(q) > 0.1)).map(quat.normalize)


def same_rotation(a: FloatArray, b: FloatArray, atol: float = 1e-12) -> bool:
    return bool(np.all(np.abs(np.abs(np.sum(a * b, axis=-1)) - 1.0) < atol))


def wrapped(d: FloatArray) -> FloatArray:
    """Angle differences wrapped to (−π, π]: π and −π are the same angle."""
    return np.asarray(np.pi - np.mod(np.pi - d, 2.0 * np.pi))


def elementary_matrix(axis: str, angle: float) -> FloatArray:
    c, s = np.cos(angle), np.sin(angle)
    if axis == "x":
        return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])
    if axis == "y":
        return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])


def lock_angles(order: str, rng: np.random.Generator, n: int) -> FloatArray:
    """Euler angles exactly at gimbal lock (middle angle at a singular value) for ``order``."""
    middle = [0.0, np.pi] if is_proper(order) else [np.pi / 2, -np.pi / 2]
    a = rng.uniform(-np.pi, np.pi, size=(n, 3))
    a[:, 1] = np.resize(middle, n)
    return a


def test_all_24_order_strings_are_covered() -> None:
    assert len(set(ORDERS)) == 24
    for order in ORDERS:
        euler.parse_order(order)


# --- round trips --------------------------------------------------------------------------


@pytest.mark.parametrize("order", ORDERS)
def test_quaternion_euler_quaternion_round_trip(order: str, random_quats: FloatArray) -> None:
    angles = euler.to_euler(random_quats, order)
    assert angles.shape == (len(random_quats), 3)
    assert same_rotation(euler.from_euler(angles, order), random_quats)


@pytest.mark.parametrize("order", ORDERS)
def test_euler_ranges(order: str, random_quats: FloatArray) -> None:
    a = euler.to_euler(random_quats, order)
    assert np.all((a[:, [0, 2]] > -np.pi) & (a[:, [0, 2]] <= np.pi))
    lo, hi = (0.0, np.pi) if is_proper(order) else (-np.pi / 2, np.pi / 2)
    assert np.all((a[:, 1] >= lo - 1e-12) & (a[:, 1] <= hi + 1e-12))


@settings(max_examples=200, deadline=None)
@given(unit_quaternions(), st.sampled_from(ORDERS))
def test_round_trip_property(q: FloatArray, order: str) -> None:
    assert same_rotation(euler.from_euler(euler.to_euler(q, order), order), q)


@pytest.mark.parametrize("order", ORDERS)
def test_euler_quaternion_euler_recovers_angles(order: str, rng: np.random.Generator) -> None:
    # Inside the ranges and away from the lock the angles themselves come back.
    a = rng.uniform(-np.pi + 1e-3, np.pi - 1e-3, size=(400, 3))
    a[:, 1] = rng.uniform(0.01, np.pi - 0.01, 400) if is_proper(order) else a[:, 1] / 2.0
    back = euler.to_euler(euler.from_euler(a, order), order)
    np.testing.assert_allclose(back, a, atol=1e-9)


@pytest.mark.parametrize("order", ORDERS)
def test_gimbal_lock(order: str, rng: np.random.Generator) -> None:
    a = lock_angles(order, rng, 40)
    q = euler.from_euler(a, order)
    back = euler.to_euler(q, order)
    assert np.all(np.isfinite(back))
    assert same_rotation(euler.from_euler(back, order), q)
    np.testing.assert_allclose(wrapped(back[:, 1] - a[:, 1]), 0.0, atol=1e-7)
    # The documented convention: all of the free angle goes into the first one.
    np.testing.assert_array_equal(back[:, 2], 0.0)


@pytest.mark.parametrize("order", ORDERS)
def test_near_gimbal_lock_still_round_trips(order: str, rng: np.random.Generator) -> None:
    a = lock_angles(order, rng, 40)
    a[:, 1] += rng.choice([-1.0, 1.0], 40) * rng.choice([1e-9, 1e-7, 1e-5], 40)
    q = euler.from_euler(a, order)
    assert same_rotation(euler.from_euler(euler.to_euler(q, order), order), q)


# --- against scipy (upper case = scipy intrinsic, lower case = scipy extrinsic) --------------


@pytest.mark.parametrize("order", ORDERS)
def test_from_euler_matches_scipy(order: str, rng: np.random.Generator) -> None:
    a = rng.uniform(-np.pi, np.pi, size=(300, 3))
    ref = np.roll(Rotation.from_euler(order, a).as_quat(), 1, axis=-1)
    assert same_rotation(euler.from_euler(a, order), ref)
    np.testing.assert_allclose(
        euler.matrix_from_euler(a, order), Rotation.from_euler(order, a).as_matrix(), atol=1e-12
    )


@pytest.mark.parametrize("order", ORDERS)
def test_to_euler_matches_scipy(order: str, random_quats: FloatArray) -> None:
    ours = euler.to_euler(random_quats, order)
    rot = Rotation.from_quat(np.roll(random_quats, -1, axis=-1))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)  # scipy warns about the locked samples
        ref = rot.as_euler(order)
    # Away from gimbal lock the decomposition is unique: the angles must agree.
    middle = ours[:, 1] if is_proper(order) else ours[:, 1] + np.pi / 2
    free = (middle > 1e-4) & (middle < np.pi - 1e-4)
    assert free.sum() > 400
    np.testing.assert_allclose(wrapped(ours[free] - ref[free]), 0.0, atol=1e-9)


# --- composition --------------------------------------------------------------------------


@settings(max_examples=150, deadline=None)
@given(arrays(np.float64, 3, elements=st.floats(-2 * np.pi, 2 * np.pi)), st.sampled_from(ORDERS))
def test_from_euler_is_the_product_of_elementary_rotations(a: FloatArray, order: str) -> None:
    m = [elementary_matrix(axis, angle) for axis, angle in zip(order.lower(), a, strict=True)]
    # Intrinsic: R = R0 R1 R2 (each turn about the already-turned axes); extrinsic reversed.
    expected = m[0] @ m[1] @ m[2] if order.isupper() else m[2] @ m[1] @ m[0]
    np.testing.assert_allclose(euler.matrix_from_euler(a, order), expected, atol=1e-12)
    elem = [
        quat.from_axis_angle(np.eye(3)["xyz".index(axis)], angle)
        for axis, angle in zip(order.lower(), a, strict=True)
    ]
    q_expected = (
        quat.mul(quat.mul(elem[0], elem[1]), elem[2])
        if order.isupper()
        else quat.mul(quat.mul(elem[2], elem[1]), elem[0])
    )
    np.testing.assert_allclose(euler.from_euler(a, order), q_expected, atol=1e-14)


@settings(max_examples=100, deadline=None)
@given(arrays(np.float64, 3, elements=st.floats(-np.pi, np.pi)), st.sampled_from(_TAIT_BRYAN))
def test_intrinsic_is_reversed_extrinsic(a: FloatArray, order: str) -> None:
    np.testing.assert_allclose(
        euler.from_euler(a, order), euler.from_euler(a[::-1], order[::-1].lower()), atol=1e-15
    )


def test_bvh_channel_order() -> None:
    # BVH "Zrotation Xrotation Yrotation" 90 0 0: a quarter turn about Z only.
    q = euler.from_euler(np.radians([90.0, 0.0, 0.0]), "ZXY")
    np.testing.assert_allclose(quat.rotate(q, [1.0, 0.0, 0.0]), [0.0, 1.0, 0.0], atol=1e-15)


def test_rpy_to_quat_is_urdf_fixed_axis() -> None:
    rpy = np.array([0.3, -0.7, 1.9])
    expected = (
        elementary_matrix("z", rpy[2])
        @ elementary_matrix("y", rpy[1])
        @ elementary_matrix("x", rpy[0])
    )
    np.testing.assert_allclose(quat.to_matrix(euler.rpy_to_quat(rpy)), expected, atol=1e-14)


def test_batched_shapes() -> None:
    a = np.zeros((2, 5, 3))
    assert euler.from_euler(a, "ZYX").shape == (2, 5, 4)
    assert euler.to_euler(quat.identity((2, 5)), "zxz").shape == (2, 5, 3)
    assert euler.matrix_from_euler(a, "xyz").shape == (2, 5, 3, 3)


# --- errors -------------------------------------------------------------------------------


@pytest.mark.parametrize("bad", ["XYz", "XXY", "XYY", "XY", "XYZX", "ABC", "xyw", ""])
def test_bad_order_raises(bad: str) -> None:
    with pytest.raises(ValueError, match="order"):
        euler.from_euler(np.zeros(3), bad)
    with pytest.raises(ValueError, match="order"):
        euler.to_euler(quat.identity(), bad)


def test_parse_order() -> None:
    assert euler.parse_order("ZYX") == ((2, 1, 0), True)
    assert euler.parse_order("xzx") == ((0, 2, 0), False)


def test_from_euler_needs_three_angles() -> None:
    with pytest.raises(ValueError, match="length 3"):
        euler.from_euler(np.zeros((5, 2)), "XYZ")


def test_to_euler_of_zero_quaternion_raises() -> None:
    with pytest.raises(ValueError, match="zero"):
        euler.to_euler(np.zeros(4), "XYZ")


@pytest.mark.parametrize("order", ORDERS)
def test_gimbal_lock_convention_matches_scipy(order: str, rng: np.random.Generator) -> None:
    q = euler.from_euler(lock_angles(order, rng, 40), order)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)  # scipy's "Gimbal lock detected"
        ref = Rotation.from_quat(np.roll(q, -1, axis=-1)).as_euler(order)
    np.testing.assert_allclose(wrapped(euler.to_euler(q, order) - ref), 0.0, atol=1e-7)
