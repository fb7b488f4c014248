"""The named cost terms: each residual's square is the cost its docstring states."""

from __future__ import annotations

import casadi as ca
import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from robot_retarget.optimize import FrameTargets, RetargetSettings
from robot_retarget.optimize.formulation import FrameQuantities, RobotProblem
from robot_retarget.optimize.objective import retarget_objective
from robot_retarget.optimize.terms import BoneDirectionTerm, KeypointTerm, TermContext
from robot_retarget.optimize.terms.keypoint import keypoint_chains
from robot_retarget.robot.config import RobotConfig


def _context(term_params: dict[str, ca.SX], robot: FrameQuantities, nj: int = 1) -> TermContext:
    z = ca.SX.zeros(nj, 1)
    return TermContext(q=z, q_prev=z, q_prev2=z, inv_dt=ca.SX(1.0), robot=robot, params=term_params)


@settings(max_examples=60, deadline=None)
@given(
    seed=st.integers(0, 2**31 - 1),
    eps=st.sampled_from([0.0, 1e-3, 0.05, 0.2, 1.0]),
    nb=st.integers(1, 6),
)
def test_direction_cost_is_squared_chord_or_pseudo_huber(seed: int, eps: float, nb: int) -> None:
    rng = np.random.default_rng(seed)
    d = rng.normal(size=(nb, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    t = rng.normal(size=(nb, 3))
    t /= np.linalg.norm(t, axis=1, keepdims=True)
    w = rng.uniform(0.0, 3.0, size=nb)
    term = BoneDirectionTerm(w, eps)
    dirs, target, weight = ca.SX.sym("d", 3 * nb), ca.SX.sym("t", 3 * nb), ca.SX.sym("w", nb)
    robot = FrameQuantities(dirs, ca.SX(0, 1), ca.SX(0, 1), ca.SX(0, 1))
    r = term.residual(_context({"target": target, "weight": weight}, robot))
    cost = float(ca.Function("c", [dirs, target, weight], [ca.sumsqr(r)])(d.ravel(), t.ravel(), w))
    c = np.linalg.norm(d - t, axis=1)
    want = np.sum(w * c**2) if eps == 0.0 else np.sum(w * (np.sqrt(c**2 + eps**2) - eps))
    assert cost == np.float64(want) or abs(cost - want) <= 1e-12 * (1.0 + want)


def test_pseudo_huber_is_smooth_at_a_matched_bone() -> None:
    term = BoneDirectionTerm(np.ones(1), 0.1)
    dirs = ca.SX.sym("d", 3)
    robot = FrameQuantities(dirs, ca.SX(0, 1), ca.SX(0, 1), ca.SX(0, 1))
    target = ca.SX([0.0, 0.0, 1.0])
    r = term.residual(_context({"target": target, "weight": ca.SX(1.0)}, robot))
    hess = ca.Function("h", [dirs], [ca.hessian(ca.sumsqr(r), dirs)[0]])
    # At c = 0 the cost is c² / (2·eps): Hessian I / eps, finite.
    np.testing.assert_allclose(np.asarray(hess([0.0, 0.0, 1.0])), np.eye(3) / 0.1, atol=1e-9)


def test_keypoint_chains_walk_each_limb_from_its_root() -> None:
    starts = ("body", "sho", "elbow", "hip", "knee", "ankle")
    ends = ("neck", "elbow", "hand", "knee", "ankle", "toe")
    canonical_ends = ("Neck", "LeftForeArm", "LeftHand", "LeftLeg", "LeftFoot", "LeftToeBase")
    rows = keypoint_chains(starts, ends, canonical_ends)
    np.testing.assert_array_equal(
        rows,
        [
            [0, 1, 0, 0, 0, 0],  # elbow: upper arm
            [0, 1, 1, 0, 0, 0],  # hand: upper arm + forearm
            [0, 0, 0, 1, 0, 0],  # knee
            [0, 0, 0, 1, 1, 0],  # ankle (the toe is not a keypoint)
        ],
    )


@settings(max_examples=10, deadline=None)
@given(seed=st.integers(0, 2**31 - 1))
def test_keypoints_vanish_at_the_pose_the_directions_came_from(op3: RobotConfig, seed: int) -> None:
    prob = RobotProblem(op3)
    obj = retarget_objective(prob, RetargetSettings(w_keypoint=50.0))
    term = next(t for t in obj.terms if isinstance(t, KeypointTerm))
    nlp = prob.build_nlp(1, obj)
    r = ca.Function("r", [nlp["x"], nlp["p"]], [nlp["r"]])
    q = np.random.default_rng(seed).uniform(op3.lower, op3.upper)
    p = np.zeros(obj.layout.size(1))
    writer = obj.writer(p, 1)
    writer.write_frame(0, FrameTargets(np.asarray(prob.directions_function(q)).T))
    target = p[obj.layout.frame(0, "keypoint.target")]
    assert np.abs(target).max() > 0.05  # elbows and hands are decimetres from their roots
    keypoint_rows = np.asarray(r(q, p)).ravel()[-target.size :]
    np.testing.assert_allclose(keypoint_rows, 0.0, atol=1e-9)
    assert term.chains.shape == (8, len(prob.bones))
