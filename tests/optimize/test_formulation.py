"""The NLP building blocks: the one-row twist, the parameter layout, problem sizes."""

from __future__ import annotations

import casadi as ca
import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from robot_retarget.geometry import quaternion as quat
from robot_retarget.optimize.formulation import FrameLayout, RobotProblem, twist_expr
from robot_retarget.robot.config import RobotConfig

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


def test_layout_slices_tile_the_frame_block() -> None:
    lay = FrameLayout(num_bones=5, num_ee=3)
    covered = np.zeros(lay.size, dtype=int)
    for sl in (lay.dirs, lay.normals, lay.w_dir, lay.w_ori, lay.ee, lay.w_ee):
        covered[sl] += 1
    assert np.all(covered == 1)


def test_problem_sizes(op3: RobotConfig) -> None:
    prob = RobotProblem(op3)
    nlp = prob.build_nlp(3)
    j = op3.num_joints
    assert nlp["x"].shape == (3 * j, 1)
    assert nlp["p"].shape == (3 * prob.layout.size + prob.shared_param_size(), 1)
    assert nlp["g"].shape == (3 * prob.num_constraints_per_frame + 2 * j, 1)
    assert prob.num_constraints_per_frame == len(prob.bones) + len(prob.feet)
