"""Torch quaternions against the numpy reference, gradients, dtypes and devices."""

from __future__ import annotations

import itertools
from collections.abc import Callable

import numpy as np
import numpy.typing as npt
import pytest
import torch
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from robot_retarget.geometry import euler as np_euler
from robot_retarget.geometry import quaternion as npq
from robot_retarget.nn import quaternion_torch as tq

FloatArray = npt.NDArray[np.float64]

_TAIT_BRYAN = ["".join(p) for p in itertools.permutations("XYZ")]
_PROPER = [a + b + a for a in "XYZ" for b in "XYZ" if a != b]
ORDERS = [o for base in _TAIT_BRYAN + _PROPER for o in (base, base.lower())]
DEVICES = ["cpu", *(["cuda"] if torch.cuda.is_available() else [])]


def t64(x: npt.ArrayLike) -> torch.Tensor:
    return torch.as_tensor(np.ascontiguousarray(x, dtype=np.float64))


def close(actual: torch.Tensor, expected: npt.ArrayLike, atol: float = 1e-12) -> None:
    assert actual.dtype == torch.float64
    np.testing.assert_allclose(actual.detach().cpu().numpy(), expected, rtol=0.0, atol=atol)


def wrapped(d: FloatArray) -> FloatArray:
    return np.asarray(np.pi - np.mod(np.pi - d, 2.0 * np.pi))


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(314)


@pytest.fixture
def quats(rng: np.random.Generator) -> FloatArray:
    """(N, 4): random unit quaternions, both signs, plus identity, half-turns and near-zero and
    near-π rotations about the coordinate axes and random axes."""
    uniform = npq.normalize(rng.normal(size=(400, 4)))
    axes = np.concatenate([np.eye(3), rng.normal(size=(10, 3))])
    angles = np.array([0.0, 1e-13, 1e-9, 1e-6, 1.0, np.pi - 1e-9, np.pi])
    special = npq.from_axis_angle(np.repeat(axes, len(angles), 0), np.tile(angles, len(axes)))
    return np.concatenate([uniform, special, -special])


@pytest.fixture
def other_quats(quats: FloatArray, rng: np.random.Generator) -> FloatArray:
    """Partners for ``quats``: random ones, the same ones, negated ones and nearly equal ones."""
    n = len(quats)
    out = npq.normalize(rng.normal(size=(n, 4)))
    pick = rng.integers(0, 4, size=n)
    nudge = npq.from_rotation_vector(rng.normal(size=(n, 3)) * 1e-10)
    out = np.where((pick == 1)[:, None], quats, out)
    out = np.where((pick == 2)[:, None], -quats, out)
    return np.where((pick == 3)[:, None], npq.mul(quats, nudge), out)


@pytest.fixture
def vecs(quats: FloatArray, rng: np.random.Generator) -> FloatArray:
    """(N, 3) vectors of mixed scales, including ±coordinate axes."""
    v = rng.normal(size=(len(quats), 3)) * rng.choice([1e-3, 1.0, 1e3], size=(len(quats), 1))
    v[:6] = np.concatenate([np.eye(3), -np.eye(3)])
    return v


# --- agreement with numpy (float64, 1e-12) --------------------------------------------------


def test_identity() -> None:
    q = tq.identity((2, 3), dtype=torch.float64)
    assert q.shape == (2, 3, 4)
    close(q, npq.identity((2, 3)), atol=0.0)
    assert tq.identity(dtype=torch.float32).dtype == torch.float32


def test_products_and_conjugates_agree(quats: FloatArray, other_quats: FloatArray) -> None:
    close(tq.mul(t64(quats), t64(other_quats)), npq.mul(quats, other_quats))
    close(tq.conjugate(t64(quats)), npq.conjugate(quats), atol=0.0)
    close(tq.canonical_sign(t64(quats)), npq.canonical_sign(quats), atol=0.0)
    close(tq.normalize(t64(quats * 3.7)), npq.normalize(quats * 3.7))


def test_rotate_and_matrices_agree(quats: FloatArray, vecs: FloatArray) -> None:
    scale = float(np.abs(vecs).max())  # vectors up to ~1e3 long: the tolerance is relative
    close(tq.rotate(t64(quats), t64(vecs)), npq.rotate(quats, vecs), atol=1e-12 * scale)
    close(tq.to_matrix(t64(quats)), npq.to_matrix(quats))
    m = npq.to_matrix(quats)
    close(tq.from_matrix(t64(m)), npq.from_matrix(m))


def test_axis_angle_and_rotation_vectors_agree(quats: FloatArray, vecs: FloatArray) -> None:
    axis, angle = tq.to_axis_angle(t64(quats))
    np_axis, np_angle = npq.to_axis_angle(quats)
    close(axis, np_axis)
    close(angle, np_angle)
    close(tq.to_rotation_vector(t64(quats)), npq.to_rotation_vector(quats))
    rv = npq.to_rotation_vector(quats)
    close(tq.from_rotation_vector(t64(rv)), npq.from_rotation_vector(rv))
    angles = np.linspace(-4.0, 4.0, len(vecs))
    close(tq.from_axis_angle(t64(vecs), t64(angles)), npq.from_axis_angle(vecs, angles))


def test_distances_and_interpolation_agree(
    quats: FloatArray, other_quats: FloatArray, rng: np.random.Generator
) -> None:
    close(tq.angle_between(t64(quats), t64(other_quats)), npq.angle_between(quats, other_quats))
    t = rng.uniform(-0.2, 1.2, size=len(quats))
    t[:3] = [0.0, 0.5, 1.0]
    close(tq.slerp(t64(quats), t64(other_quats), t64(t)), npq.slerp(quats, other_quats, t))
    close(tq.slerp(t64(quats), t64(other_quats), 0.25), npq.slerp(quats, other_quats, 0.25))


def test_swing_twist_agrees(quats: FloatArray, vecs: FloatArray) -> None:
    swing, twist = tq.swing_twist(t64(quats), t64(vecs))
    np_swing, np_twist = npq.swing_twist(quats, vecs)
    close(swing, np_swing)
    close(twist, np_twist)
    close(tq.twist_angle(t64(quats), t64(vecs)), npq.twist_angle(quats, vecs))
    # One axis for the whole batch broadcasts.
    close(tq.swing_twist(t64(quats), t64([0.0, 0, 1]))[1], npq.swing_twist(quats, [0.0, 0, 1])[1])


def test_from_two_vectors_agrees(vecs: FloatArray, rng: np.random.Generator) -> None:
    b = rng.normal(size=vecs.shape)
    b[:10] = -vecs[:10] * 2.0  # opposite
    b[10:20] = vecs[10:20] * 0.5  # parallel
    close(tq.from_two_vectors(t64(vecs), t64(b)), npq.from_two_vectors(vecs, b))


def test_make_continuous_agrees(quats: FloatArray, rng: np.random.Generator) -> None:
    seq = quats[:400].reshape(20, 20, 4) * rng.choice([-1.0, 1.0], size=(20, 20, 1))
    close(tq.make_continuous(t64(seq)), npq.make_continuous(seq), atol=0.0)
    close(tq.make_continuous(t64(seq), axis=1), npq.make_continuous(seq, axis=1), atol=0.0)
    close(tq.make_continuous(t64(seq[:1])), seq[:1], atol=0.0)


@pytest.mark.parametrize("order", ORDERS)
def test_euler_agrees_in_every_order(
    order: str, quats: FloatArray, rng: np.random.Generator
) -> None:
    ours = tq.to_euler(t64(quats), order).numpy()
    # ±π are the same angle: compare wrapped differences.
    np.testing.assert_allclose(wrapped(ours - np_euler.to_euler(quats, order)), 0.0, atol=1e-12)
    angles = rng.uniform(-4.0, 4.0, size=(300, 3))
    close(tq.from_euler(t64(angles), order), np_euler.from_euler(angles, order))
    close(tq.matrix_from_euler(t64(angles), order), np_euler.matrix_from_euler(angles, order))


@pytest.mark.parametrize("order", ORDERS)
def test_euler_agrees_at_gimbal_lock(order: str, rng: np.random.Generator) -> None:
    proper = order[0].lower() == order[2].lower()
    a = rng.uniform(-np.pi, np.pi, size=(40, 3))
    a[:, 1] = np.resize([0.0, np.pi] if proper else [np.pi / 2, -np.pi / 2], 40)
    q = np_euler.from_euler(a, order)
    ours = tq.to_euler(t64(q), order).numpy()
    np.testing.assert_allclose(wrapped(ours - np_euler.to_euler(q, order)), 0.0, atol=1e-12)


def test_rpy_agrees() -> None:
    rpy = np.array([[0.1, -0.2, 2.9], [np.pi, 0.0, -np.pi / 2]])
    close(tq.rpy_to_quat(t64(rpy)), np_euler.rpy_to_quat(rpy))


@settings(max_examples=100, deadline=None)
@given(
    arrays(np.float64, (5, 4), elements=st.floats(-1.0, 1.0)).filter(
        lambda q: bool(np.all(np.linalg.norm(q, axis=-1) > 0.1))
    ),
    arrays(np.float64, (5, 3), elements=st.floats(-3.0, 3.0)),
)
def test_agreement_property(raw: FloatArray, v: FloatArray) -> None:
    q = npq.normalize(raw)
    r = q[::-1]
    close(tq.mul(t64(q), t64(r)), npq.mul(q, r))
    close(tq.rotate(t64(q), t64(v)), npq.rotate(q, v))
    close(tq.from_matrix(t64(npq.to_matrix(q))), npq.from_matrix(npq.to_matrix(q)))
    close(tq.to_rotation_vector(t64(q)), npq.to_rotation_vector(q))
    close(tq.from_rotation_vector(t64(v)), npq.from_rotation_vector(v))
    close(tq.angle_between(t64(q), t64(r)), npq.angle_between(q, r))
    close(tq.slerp(t64(q), t64(r), 0.3), npq.slerp(q, r, 0.3))


# --- 6D representation ----------------------------------------------------------------------


def test_rotation_6d_round_trips(quats: FloatArray) -> None:
    q = t64(quats)
    m = tq.to_matrix(q)
    d6 = tq.matrix_to_rotation_6d(m)
    assert d6.shape == (len(quats), 6)
    close(tq.rotation_6d_to_matrix(d6), m.numpy())
    close(tq.from_rotation_6d(tq.to_rotation_6d(q)), npq.canonical_sign(quats))


def test_rotation_6d_of_any_input_is_a_rotation(rng: np.random.Generator) -> None:
    m = tq.rotation_6d_to_matrix(t64(rng.normal(size=(200, 6)) * 5.0))
    close(m @ m.transpose(-1, -2), np.broadcast_to(np.eye(3), (200, 3, 3)))
    close(torch.linalg.det(m), np.ones(200))
    # The first column is the normalised first 3-vector (Gram–Schmidt keeps its direction).
    d6 = t64([[2.0, 0.0, 0.0, 1.0, 1.0, 0.0]])
    close(tq.rotation_6d_to_matrix(d6)[0], np.eye(3))


# --- shape errors ---------------------------------------------------------------------------


def test_shape_and_order_errors() -> None:
    with pytest.raises(ValueError, match="length 3"):
        tq.from_euler(torch.zeros(5, 2), "XYZ")
    with pytest.raises(ValueError, match="length 4"):
        tq.to_euler(torch.zeros(5, 3), "XYZ")
    with pytest.raises(ValueError, match="order"):
        tq.from_euler(torch.zeros(3), "XYX ")
    with pytest.raises(ValueError, match="length 6"):
        tq.rotation_6d_to_matrix(torch.zeros(9))


def test_broadcasting() -> None:
    q = tq.normalize(torch.randn(2, 3, 4, dtype=torch.float64))
    assert tq.mul(q, q[0]).shape == (2, 3, 4)
    assert tq.rotate(q, torch.ones(3, dtype=torch.float64)).shape == (2, 3, 3)
    assert tq.from_axis_angle(torch.tensor([0.0, 0.0, 1.0]), torch.zeros(5)).shape == (5, 4)
    assert tq.swing_twist(q, torch.ones(3, dtype=torch.float64))[0].shape == (2, 3, 4)
    assert tq.from_two_vectors(torch.ones(5, 3), torch.ones(3)).shape == (5, 4)
    assert tq.slerp(q, q, torch.linspace(0, 1, 3, dtype=torch.float64)).shape == (2, 3, 4)


# --- gradients ------------------------------------------------------------------------------

GRADCHECKED: dict[str, Callable[..., torch.Tensor]] = {
    "normalize": lambda x: tq.normalize(x[..., :4]),
    "mul": lambda x: tq.mul(x[..., :4], x[..., 4:8]),
    "rotate": lambda x: tq.rotate(x[..., :4], x[..., 4:7]),
    "from_matrix": lambda x: tq.from_matrix(tq.to_matrix(tq.normalize(x[..., :4]))),
    "to_rotation_vector": lambda x: tq.to_rotation_vector(tq.normalize(x[..., :4])),
    "from_rotation_vector": lambda x: tq.from_rotation_vector(x[..., :3]),
    "angle_between": lambda x: tq.angle_between(
        tq.normalize(x[..., :4]), tq.normalize(x[..., 4:8])
    ),
    "slerp": lambda x: tq.slerp(tq.normalize(x[..., :4]), tq.normalize(x[..., 4:8]), x[..., 8]),
    "swing_twist": lambda x: torch.cat(tq.swing_twist(tq.normalize(x[..., :4]), x[..., 4:7]), -1),
    "twist_angle": lambda x: tq.twist_angle(tq.normalize(x[..., :4]), x[..., 4:7]),
    "from_two_vectors": lambda x: tq.from_two_vectors(x[..., :3], x[..., 3:6]),
    "to_euler_ZYX": lambda x: tq.to_euler(x[..., :4], "ZYX"),
    "to_euler_zxz": lambda x: tq.to_euler(x[..., :4], "zxz"),
    "from_euler_YXZ": lambda x: tq.from_euler(x[..., :3], "YXZ"),
    "rotation_6d_to_matrix": lambda x: tq.rotation_6d_to_matrix(x[..., :6]),
}


@pytest.mark.parametrize("name", sorted(GRADCHECKED))
def test_gradcheck(name: str) -> None:
    x = torch.randn(3, 9, dtype=torch.float64, generator=torch.Generator().manual_seed(11))
    x[..., 8] = torch.rand(3, dtype=torch.float64)  # slerp's t in [0, 1)
    x.requires_grad_(True)
    assert torch.autograd.gradcheck(GRADCHECKED[name], (x,), eps=1e-6, atol=1e-6)


def _grad_of(fn: Callable[[torch.Tensor], torch.Tensor], x: FloatArray) -> torch.Tensor:
    xt = t64(x).requires_grad_(True)
    out = fn(xt)
    assert torch.all(torch.isfinite(out))
    (
        out * torch.linspace(0.5, 1.5, out.numel(), dtype=out.dtype).reshape(out.shape)
    ).sum().backward()
    assert xt.grad is not None
    return xt.grad


IDENTITY = np.array([[1.0, 0.0, 0.0, 0.0]])
HALF_TURN_X = np.array([[0.0, 1.0, 0.0, 0.0]])
SOME_Q = npq.normalize([[0.2, 0.3, -0.4, 0.5]])
Y_HAT = np.array([[0.0, 1.0, 0.0]])


def _z(like: torch.Tensor) -> torch.Tensor:
    return torch.tensor([0.0, 0.0, 1.0], dtype=like.dtype, device=like.device)


def _axis_angle_cat(q: torch.Tensor) -> torch.Tensor:
    axis, angle = tq.to_axis_angle(q)
    return torch.cat([axis, angle[..., None]], dim=-1)


DEGENERATE: dict[str, tuple[Callable[[torch.Tensor], torch.Tensor], FloatArray]] = {
    "normalize(0)": (tq.normalize, np.zeros((1, 4))),
    "from_rotation_vector(0)": (tq.from_rotation_vector, np.zeros((1, 3))),
    "to_rotation_vector(1)": (tq.to_rotation_vector, IDENTITY),
    "to_rotation_vector(0)": (tq.to_rotation_vector, np.zeros((1, 4))),
    "to_axis_angle(1)": (_axis_angle_cat, IDENTITY),
    "angle_between(q, q)": (lambda q: tq.angle_between(q, q.detach()), SOME_Q),
    "slerp(q, q)": (lambda q: tq.slerp(q, q.detach(), 0.3), SOME_Q),
    "from_matrix(I)": (lambda q: tq.from_matrix(tq.to_matrix(q)), IDENTITY),
    "from_matrix(half-turn)": (lambda q: tq.from_matrix(tq.to_matrix(q)), HALF_TURN_X),
    "swing_twist(perpendicular half-turn)": (
        lambda q: torch.cat(tq.swing_twist(q, _z(q)), dim=-1),
        HALF_TURN_X,
    ),
    "twist_angle(perpendicular half-turn)": (lambda q: tq.twist_angle(q, _z(q)), HALF_TURN_X),
    "from_two_vectors(parallel)": (lambda v: tq.from_two_vectors(v, v.detach() * 2), Y_HAT),
    "from_two_vectors(opposite)": (lambda v: tq.from_two_vectors(v, -v.detach()), Y_HAT),
    "from_two_vectors(0)": (lambda v: tq.from_two_vectors(v, torch.ones_like(v)), Y_HAT * 0),
    "rotation_6d_to_matrix(parallel)": (tq.rotation_6d_to_matrix, np.array([[1.0, 0, 0, 2, 0, 0]])),
}


@pytest.mark.parametrize("name", sorted(DEGENERATE))
def test_gradients_finite_at_degenerate_inputs(name: str) -> None:
    fn, x = DEGENERATE[name]
    assert torch.all(torch.isfinite(_grad_of(fn, x)))


@pytest.mark.parametrize("order", ORDERS)
def test_euler_gradients_finite_at_gimbal_lock(order: str) -> None:
    proper = order[0].lower() == order[2].lower()
    for middle in [0.0, np.pi] if proper else [np.pi / 2, -np.pi / 2]:
        q = np_euler.from_euler(np.array([[0.4, middle, -1.1]]), order)
        assert torch.all(torch.isfinite(_grad_of(lambda x: tq.to_euler(x, order), q)))
    grad = _grad_of(lambda x: tq.to_euler(x, order), IDENTITY)
    assert torch.all(torch.isfinite(grad))


def test_rotation_vector_jacobian_at_identity_is_exact() -> None:
    # d(rotvec)/d(v) at the identity is 2·I (angle = 2|v| to first order); d/dw is 0.
    jac = torch.autograd.functional.jacobian(tq.to_rotation_vector, t64([1.0, 0.0, 0.0, 0.0]))
    close(jac, np.concatenate([np.zeros((3, 1)), 2.0 * np.eye(3)], axis=1))
    jac = torch.autograd.functional.jacobian(tq.from_rotation_vector, t64([0.0, 0.0, 0.0]))
    close(jac, np.concatenate([np.zeros((1, 3)), 0.5 * np.eye(3)]))


# --- dtypes and devices ---------------------------------------------------------------------


@pytest.mark.parametrize("device", DEVICES)
def test_float32_on_every_device(device: str, quats: FloatArray, vecs: FloatArray) -> None:
    q = torch.as_tensor(quats, dtype=torch.float32, device=device)
    unit_vecs = vecs / np.linalg.norm(vecs, axis=-1, keepdims=True)
    v = torch.as_tensor(unit_vecs, dtype=torch.float32, device=device)
    exact = {
        "mul": (tq.mul(q, q), npq.mul(quats, quats)),
        "rotate": (tq.rotate(q, v), npq.rotate(quats, v.double().cpu().numpy())),
        "slerp": (tq.slerp(q, q.flip(0), 0.5), npq.slerp(quats, quats[::-1], 0.5)),
    }
    # Where w ≈ 0 (half-turns) float32 rounding may pick the other sign or the opposite rotation
    # vector: compare the rotations these represent.
    rotations = {
        "from_matrix": tq.from_matrix(tq.to_matrix(q)),
        "euler": tq.from_euler(tq.to_euler(q, "ZXY"), "ZXY"),
        "6d": tq.from_rotation_6d(tq.to_rotation_6d(q)),
        "rotvec": tq.from_rotation_vector(tq.to_rotation_vector(q)),
    }
    for name, (out, ref) in exact.items():
        assert out.dtype == torch.float32, name
        assert out.device.type == device, name
        np.testing.assert_allclose(out.double().cpu().numpy(), ref, atol=2e-5, err_msg=name)
    for name, out in rotations.items():
        assert out.dtype == torch.float32, name
        assert out.device.type == device, name
        dots = np.sum(out.double().cpu().numpy() * quats, axis=-1)
        assert np.all(np.abs(np.abs(dots) - 1.0) < 1e-5), name


@pytest.mark.parametrize("device", DEVICES)
def test_float32_gradients_finite(device: str) -> None:
    x = torch.zeros(4, 4, device=device)
    x[:, 0] = 1.0
    x.requires_grad_(True)
    loss = (
        tq.to_rotation_vector(x).sum()
        + tq.angle_between(x, x.detach()).sum()
        + tq.to_euler(x, "XYZ").sum()
        + tq.slerp(x, x.detach(), 0.5).sum()
    )
    loss.backward()
    assert x.grad is not None
    assert torch.all(torch.isfinite(x.grad))


def test_normalize_of_zero_is_zero_not_nan() -> None:
    out = tq.normalize(torch.zeros(2, 4))
    assert torch.equal(out, torch.zeros(2, 4))
