"""Checks every numpy runtime must pass: its export round-trips, and any finite stream gives
finite unit rotations."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from robot_retarget.geometry import quaternion as quat
from robot_retarget.runtime.model import RuntimeModel, load_runtime, save_runtime
from robot_retarget.skeleton.canonical import default_canonical_skeleton


def smooth_clip(frames: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Smooth random rotations (T, 22, 4) and a wandering, turning root (T, 3)."""
    rng = np.random.default_rng(seed)
    rot = 0.3 * rng.normal(size=(1, 22, 3)) + np.cumsum(rng.normal(0, 0.05, (frames, 22, 3)), 0)
    root = np.cumsum(rng.normal(0, 0.02, (frames, 3)), 0) + np.array([0.0, 0.9, 0.0])
    return quat.from_rotation_vector(rot), root


def assert_same_steps(
    a: RuntimeModel, b: RuntimeModel, *, frames: int, seed: int, scale: float, atol: float
) -> None:
    """Both runtimes, stepped over the same smooth clip onto ``scale`` × the reference
    skeleton, give the same outputs: to ``atol``, or bit for bit when it is 0."""
    src = default_canonical_skeleton().offsets
    quats, root = smooth_clip(frames, seed=seed)
    step_a, step_b = a.online(src, scale * src), b.online(src, scale * src)
    for t in range(len(quats)):
        for x, y in zip(
            step_a.step(quats[t], root[t]), step_b.step(quats[t], root[t]), strict=True
        ):
            if atol == 0.0:
                np.testing.assert_array_equal(x, y)
            else:
                np.testing.assert_allclose(x, y, rtol=0, atol=atol)


def assert_export_round_trip(runtime: RuntimeModel, path: Path) -> None:
    """Saved and loaded again, the runtime steps as before (to float32 storage)."""
    back = load_runtime(save_runtime(runtime, path))
    assert back.architecture == runtime.architecture
    assert_same_steps(runtime, back, frames=40, seed=2, scale=0.5, atol=1e-6)


def assert_finite_unit_outputs(runtime: RuntimeModel, raw: np.ndarray, root: np.ndarray) -> None:
    """Any finite rotations (zero or scaled ones included) and roots → finite unit outputs."""
    src = default_canonical_skeleton().offsets
    step = runtime.online(src, 0.35 * src)
    for t in range(len(raw)):
        q, pos = step.step(raw[t], root[t])
        assert np.all(np.isfinite(q))
        assert np.all(np.isfinite(pos))
        np.testing.assert_allclose(np.linalg.norm(q, axis=-1), 1.0, atol=1e-9)
