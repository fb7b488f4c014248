"""The per-frame cost as a list of named terms, and the one parameter layout generated from it.

:class:`Objective` collects the terms (:mod:`.terms`), prefixes each term's parameters with its
name (``bone_direction.target``, ``velocity.weight``, …), adds the committed history every
smoothness term reads (``history.q_prev``, ``history.q_prev2``, ``history.inv_dt``) and lays
everything out once (:class:`.parameter_layout.ParameterLayout`). The NLP builder
(:meth:`.formulation.RobotProblem.build_nlp`) asks it for each frame's residuals; the Retargeter
fills a solver's parameter vector through :meth:`Objective.writer`. Adding a cost term is one
new :class:`.terms.CostTerm` in the list of :func:`retarget_objective`; no offsets to edit.
"""

from __future__ import annotations

from collections.abc import Sequence

import casadi as ca
import numpy as np

from robot_retarget.array_types import FloatArray
from robot_retarget.optimize.formulation import FrameQuantities, RobotProblem
from robot_retarget.optimize.parameter_layout import Parameter, ParameterLayout
from robot_retarget.optimize.targets import FrameTargets
from robot_retarget.optimize.terms import (
    AccelerationTerm,
    BoneDirectionTerm,
    BoneOrientationTerm,
    CostTerm,
    EndEffectorTerm,
    PosturePullTerm,
    TermContext,
    VelocityTerm,
)
from robot_retarget.optimize.terms.keypoint import KeypointTerm, keypoint_chains
from robot_retarget.robot.retarget_settings import RetargetSettings

_Q_PREV = "history.q_prev"
_Q_PREV2 = "history.q_prev2"
_INV_DT = "history.inv_dt"


class Objective:
    """Named cost terms of one robot and the parameter layout they define."""

    def __init__(self, terms: Sequence[CostTerm], num_joints: int) -> None:
        names = [t.name for t in terms]
        if len(set(names)) != len(names):
            raise ValueError(f"cost terms must have distinct names, got {names}")
        self.terms = tuple(terms)
        self.num_joints = num_joints
        self._local = tuple(tuple(p.name for p in t.parameters()) for t in self.terms)
        history = (
            Parameter(_Q_PREV, num_joints, shared=True),
            Parameter(_Q_PREV2, num_joints, shared=True),
            Parameter(_INV_DT, 1, shared=True),
        )
        self.layout = ParameterLayout(
            [
                *history,
                *(
                    Parameter(f"{t.name}.{p.name}", p.size, p.shared)
                    for t in self.terms
                    for p in t.parameters()
                ),
            ]
        )

    def term_slices(self, t: int, k: int) -> dict[str, slice]:
        prefix = f"{self.terms[k].name}."
        full = self.layout.slices(t, [prefix + n for n in self._local[k]])
        return {n: full[prefix + n] for n in self._local[k]}

    def residuals(
        self, t: int, p: ca.SX, q: ca.SX, history: tuple[ca.SX, ca.SX], robot: FrameQuantities
    ) -> list[ca.SX]:
        """Weighted residuals of frame ``t`` of a window (cost: the sum of their squares).
        ``history``: (q_{t−2}, q_{t−1})."""
        out = []
        for k, term in enumerate(self.terms):
            params = {n: p[sl] for n, sl in self.term_slices(t, k).items()}
            ctx = TermContext(
                q=q,
                q_prev=history[1],
                q_prev2=history[0],
                inv_dt=p[self.layout.shared(_INV_DT)],
                robot=robot,
                params=params,
            )
            out.append(term.residual(ctx))
        return out

    def history(self, p: ca.SX) -> tuple[ca.SX, ca.SX]:
        """(q_{−2}, q_{−1}) of a window: the committed history parameters."""
        return p[self.layout.shared(_Q_PREV2)], p[self.layout.shared(_Q_PREV)]

    def history_slices(self) -> tuple[slice, slice, slice]:
        """Where ``p`` holds the history: (q_{t−1}, q_{t−2}, 1/dt)."""
        lay = self.layout
        return lay.shared(_Q_PREV), lay.shared(_Q_PREV2), lay.shared(_INV_DT)

    def writer(self, p: FloatArray, window: int) -> ParameterWriter:
        """Writes a solver's parameter vector ``p`` (laid out for ``window`` frames) in place."""
        return ParameterWriter(self, p, window)


class ParameterWriter:
    """Numpy views of one solver's parameters, per frame and term; constants written here."""

    def __init__(self, objective: Objective, p: FloatArray, window: int) -> None:
        if p.shape != (objective.layout.size(window),):
            raise ValueError(
                f"parameter vector has shape {p.shape}, the layout of {window} frames needs "
                f"({objective.layout.size(window)},)"
            )
        self.objective = objective
        self.window = window
        terms = objective.terms
        self._views = [
            [{n: p[sl] for n, sl in objective.term_slices(t, k).items()} for k in range(len(terms))]
            for t in range(window)
        ]
        lay = objective.layout
        self._q_prev = p[lay.shared(_Q_PREV)]
        self._q_prev2 = p[lay.shared(_Q_PREV2)]
        self._inv_dt = p[lay.shared(_INV_DT)]
        for k, term in enumerate(terms):
            term.init_shared(self._views[0][k])
            for t in range(window):
                term.init_frame(self._views[t][k])

    def write_frame(self, t: int, targets: FrameTargets) -> None:
        """Validate one frame's targets and write them into frame block ``t``."""
        for term, view in zip(self.objective.terms, self._views[t], strict=True):
            term.write_frame(view, targets)

    def write_history(self, q_prev: FloatArray, q_prev2: FloatArray, dt_s: float) -> None:
        self._q_prev[:] = q_prev
        self._q_prev2[:] = q_prev2
        self._inv_dt[0] = 1.0 / dt_s


def retarget_objective(problem: RobotProblem, settings: RetargetSettings) -> Objective:
    """The Retargeter's cost terms, in residual order, weighted by ``settings``."""
    ne = len(problem.ee_frames)
    bones = [b.canonical for b in problem.bones]
    terms: list[CostTerm] = [
        BoneDirectionTerm(
            np.array([settings.direction_weight(b) for b in bones]), settings.direction_eps
        ),
        BoneOrientationTerm(np.array([settings.orientation_weight(b) for b in bones])),
        EndEffectorTerm(ne, settings.w_end_effector, problem.config.name),
        VelocityTerm(settings.w_velocity),
        AccelerationTerm(settings.w_acceleration),
        PosturePullTerm(np.asarray(problem.config.init_pose, dtype=np.float64), settings.w_init),
    ]
    if settings.w_keypoint > 0.0:
        chains = keypoint_chains(
            tuple(b.start_frame for b in problem.bones),
            tuple(b.end_frame for b in problem.bones),
            tuple(b.canonical_end for b in problem.bones),
        )
        if chains.size:
            terms.append(KeypointTerm(chains, problem.bone_lengths, settings.w_keypoint))
    return Objective(terms, problem.num_joints)
