"""Limb keypoints at the robot's scale: ``w · Σ_k |p_k(q) − p_root(q) − Σ_{b ≤ k} L_b d*_b|²``.

GMR-style position targets without a position source: each keypoint (elbow, wrist, knee, ankle:
a limb bone's end) is placed by walking the target bone directions along the robot's own bone
lengths ``L_b`` from the limb's root (its first bone's start: shoulder, hip), and compared with
the robot's keypoint relative to that root (m, root frame). On a limb that cannot match all of
its bone directions this weighs where the hand or foot ends up, not only the angles.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import casadi as ca
import numpy as np

from robot_retarget.array_types import FloatArray
from robot_retarget.optimize.parameter_layout import Parameter
from robot_retarget.optimize.targets import FrameTargets
from robot_retarget.optimize.terms.term import CostTerm, TermContext


@dataclass(frozen=True, eq=False)  # holds arrays
class KeypointTerm(CostTerm):
    """``chains`` (K, B): row k sums the bones from keypoint k's limb root to keypoint k;
    ``lengths`` (B,) m. Per frame: the targets (K·3); shared: the weight (1/m²)."""

    name = "keypoint"
    chains: FloatArray
    lengths: FloatArray
    weight: float

    def parameters(self) -> tuple[Parameter, ...]:
        return (
            Parameter("target", 3 * self.chains.shape[0]),
            Parameter("weight", 1, shared=True),
        )

    def residual(self, ctx: TermContext) -> ca.SX:
        k, b = self.chains.shape
        vectors = ca.reshape(ctx.robot.bone_vectors, 3, b)  # columns: bone vectors
        points = ca.reshape(vectors @ ca.DM(self.chains.T), 3 * k, 1)
        return ca.sqrt(ctx.params["weight"]) * (points - ctx.params["target"])

    def init_shared(self, params: Mapping[str, FloatArray]) -> None:
        params["weight"][:] = self.weight

    def write_frame(self, params: Mapping[str, FloatArray], targets: FrameTargets) -> None:
        # Validated by the bone-direction term, which comes first.
        walked = self.chains @ (self.lengths[:, None] * np.asarray(targets.directions))
        params["target"][:] = walked.ravel()


# Canonical ends of the bones whose ends are keypoints (elbows, wrists, knees, ankles).
KEYPOINT_ENDS = frozenset(
    f"{side}{joint}" for side in ("Left", "Right") for joint in ("ForeArm", "Hand", "Leg", "Foot")
)


def keypoint_chains(
    starts: tuple[str, ...], ends: tuple[str, ...], canonical_ends: tuple[str, ...]
) -> FloatArray:
    """(K, B) chain rows for the bones (start / end frames, canonical ends) whose canonical end
    is in :data:`KEYPOINT_ENDS`: each keypoint's chain runs back through keypoint bones that
    end where the next one starts."""
    keys = [i for i, c in enumerate(canonical_ends) if c in KEYPOINT_ENDS]
    rows = np.zeros((len(keys), len(starts)))
    for r, i in enumerate(keys):
        k: int | None = i
        while k is not None:
            rows[r, k] = 1.0
            k = next((j for j in keys if ends[j] == starts[k] and rows[r, j] == 0.0), None)
    return rows
