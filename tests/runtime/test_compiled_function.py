"""Compiled per-frame steps: binding, the disk cache, the interpreted fallback, and the residual
model's compiled stages against its interpreted ones and the numpy quaternion helpers."""

from __future__ import annotations

import logging
from pathlib import Path

import casadi as ca
import numpy as np
import pytest

from robot_retarget import casadi_jit
from robot_retarget.casadi_jit import CompiledFunction, compile_graph
from robot_retarget.geometry import quaternion as quat
from robot_retarget.geometry import symbolic_quaternion as sq
from robot_retarget.runtime.loader import load_runtime_model
from robot_retarget.runtime.residual import FastResidualRetargeter
from robot_retarget.runtime.residual_weights import ResidualWeights
from robot_retarget.skeleton.canonical import default_canonical_skeleton


def _graph() -> tuple[list[ca.SX], list[ca.SX]]:
    a = ca.SX.sym("a", 8)
    b = ca.SX.sym("b", 3)
    qa: sq.Quat = [a[i] for i in range(4)]
    qb: sq.Quat = [a[4 + i] for i in range(4)]
    r = sq.rotvec(sq.qmul(qa, qb))
    return [a, b], [ca.vertcat(*r), ca.vertcat(*sq.from_rotvec([b[0], b[1], b[2]]))]


def _unit(rng: np.random.Generator, n: int) -> np.ndarray:
    q = rng.normal(size=(n, 4))
    return q / np.linalg.norm(q, axis=-1, keepdims=True)


def test_symbolic_helpers_equal_the_numpy_ones(tmp_path: Path) -> None:
    fn = CompiledFunction(compile_graph("t_helpers", *_graph(), jit=False))
    rng = np.random.default_rng(0)
    for _ in range(20):
        q = _unit(rng, 2)
        r = rng.normal(size=3) * rng.choice([1e-9, 1e-3, 1.0, 3.0])
        fn.args[0][:] = q.ravel()
        fn.args[1][:] = r
        fn()
        want = quat.to_rotation_vector(quat.mul(q[0], q[1]))
        np.testing.assert_allclose(fn.res[0], want, atol=1e-12)
        np.testing.assert_allclose(fn.res[1], quat.from_rotation_vector(r), atol=1e-12)
    # The matrix of a unit quaternion is quat.rotate's.
    q = _unit(rng, 1)[0]
    m = ca.Function("m", [], [ca.vertcat(*sq.matrix([ca.SX(float(c)) for c in q]))])()["o0"]
    np.testing.assert_allclose(
        np.array(m).reshape(3, 3), quat.rotate(q[None], np.eye(3)).T, atol=1e-12
    )


def test_compiled_and_cached_equals_interpreted(tmp_path: Path) -> None:
    if casadi_jit.find_compiler() is None:
        pytest.skip("no C compiler")
    interpreted = CompiledFunction(compile_graph("t_cache", *_graph(), jit=False))
    fn = compile_graph("t_cache", *_graph(), cache_dir=tmp_path)
    assert list(tmp_path.glob("t_cache-*.casadi"))
    # The same graph again is the function already loaded, not a second compile.
    assert compile_graph("t_cache", *_graph(), cache_dir=tmp_path) is fn
    compiled = CompiledFunction(fn)
    x = np.array([0.5, 0.5, -0.5, 0.5, 0.0, 0.6, 0.8, 0.0, 0.1, -0.2, 0.3])
    for f in (interpreted, compiled):
        f.args[0][:] = x[:8]
        f.args[1][:] = x[8:]
        f()
    for a, b in zip(interpreted.res, compiled.res, strict=True):
        np.testing.assert_allclose(a, b, rtol=0, atol=1e-15)


def test_without_a_compiler_runs_interpreted_and_says_so(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture
) -> None:
    monkeypatch.setattr(casadi_jit, "find_compiler", lambda name=None: None)
    with caplog.at_level(logging.WARNING):
        fn = compile_graph("t_nocc", *_graph(), cache_dir=tmp_path / "c")
    assert "no C compiler" in caplog.text
    assert "install gcc" in caplog.text
    assert not list(tmp_path.glob("**/*.casadi"))
    f = CompiledFunction(fn)
    f.args[1][:] = [0.0, 0.0, np.pi]
    f()
    np.testing.assert_allclose(f.res[1], [0.0, 0.0, 0.0, 1.0], atol=1e-15)


def test_binding_checks_dtype_and_size() -> None:
    fn = compile_graph("t_bind", *_graph(), jit=False)
    with pytest.raises(ValueError, match="t_bind argument 0 needs a C-contiguous float64 array"):
        CompiledFunction(fn, args=[np.zeros(8, dtype=np.float32), None])
    with pytest.raises(ValueError, match=r"argument 1 needs .* of 3 values"):
        CompiledFunction(fn, args=[None, np.zeros(4)])
    with pytest.raises(ValueError, match="has 2 results, got 1"):
        CompiledFunction(fn, res=[None])
    shared = np.zeros(3)
    f = CompiledFunction(fn, res=[shared, None])
    assert f.res[0] is shared


def test_residual_step_compiled_equals_interpreted() -> None:
    model = load_runtime_model("default")
    assert isinstance(model.weights, ResidualWeights)
    src = default_canonical_skeleton().offsets
    tgt = src * 0.4
    steps = [FastResidualRetargeter(model.weights, src, tgt, jit=jit) for jit in (True, False)]
    rng = np.random.default_rng(3)
    for t in range(30):
        q = _unit(rng, 22)
        root = np.array([0.01 * t, 0.9, 0.02 * t])
        (qa, pa), (qb, pb) = (s.step(q, root) for s in steps)
        np.testing.assert_allclose(qa, qb, rtol=0, atol=1e-12)
        np.testing.assert_allclose(pa, pb, rtol=0, atol=1e-12)


def test_memoized_graph_builds_once_per_distinct_content() -> None:
    calls: list[float] = []

    @casadi_jit.memoized_graph
    def build(scale: np.ndarray, names: dict[int, np.ndarray | None]) -> ca.Function:
        calls.append(float(scale[0]))
        x = ca.SX.sym("x")
        return ca.Function("f", [x], [x * float(scale[0])])

    first = build(np.array([2.0]), {1: np.zeros(2), 2: None})
    again = build(np.array([2.0]), {2: None, 1: np.zeros(2)})  # equal content, new objects
    other = build(np.array([3.0]), {1: np.zeros(2), 2: None})
    assert again is first
    assert other is not first
    assert calls == [2.0, 3.0]
    assert float(other(1.0)) == 3.0
