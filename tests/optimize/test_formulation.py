"""The NLP building blocks: the one-row twist, problem sizes."""

from __future__ import annotations

import casadi as ca
import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from robot_retarget.geometry import quaternion as quat
from robot_retarget.optimize.formulation import RobotProblem, twist_expr
from robot_retarget.optimize.objective import retarget_objective
from robot_retarget.robot.config import RobotConfig
from robot_retarget.robot.retarget_settings import RetargetSettings

vec3 = st.lists(st.floats(-1.0, 1.0), min_size=3, max_size=3).filter(
    lambda v: float(np.linalg.norm(v)) > 0.1
)


@settings(max_examples=200)
@given(axis=vec3, rot=vec3, scale=st.floats(0.0, 3.1))
def test_twist_row_equals_swing_twist_angle(
    axis: list[float], rot: list[float], scale: float
) -> None:
    a = np.asarray(axis) / np.linalg.norm(axis)
    q = quat.canonical_sign(quat.from_rotation_vector(np.asarray(rot) * scale))
    if q[0] < 1e-6:  # half-turns: the twist is undefined there
        return
    r = ca.SX.sym("r", 3, 3)
    fn = ca.Function("twist", [r], [twist_expr(r, a)])
    got = float(fn(quat.to_matrix(q)))
    want = float(quat.twist_angle(q, a))
    assert abs(got - want) < 1e-9


def test_problem_sizes(op3: RobotConfig) -> None:
    prob = RobotProblem(op3)
    objective = retarget_objective(prob, RetargetSettings())
    nlp = prob.build_nlp(3, objective)
    j = op3.num_joints
    nb, ne = len(prob.bones), len(prob.ee_frames)
    assert nlp["x"].shape == (3 * j, 1)
    # Per frame: directions, normals (3 + 1 each per bone), end effectors (3 + 1); shared:
    # history (2J + 1), velocity and acceleration weights, posture (J + 1).
    assert objective.layout.frame_size == 8 * nb + 4 * ne
    assert objective.layout.shared_size == 3 * j + 4
    assert nlp["p"].shape == (objective.layout.size(3), 1)
    assert nlp["g"].shape == (3 * prob.num_constraints_per_frame + 2 * j, 1)
    assert prob.num_constraints_per_frame == len(prob.bones) + len(prob.feet)
