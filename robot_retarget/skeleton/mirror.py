"""Left–right mirroring of canonical-skeleton motion (x → −x).

The canonical skeleton is symmetric about its x = 0 plane (left = +x), so the mirror of a pose
swaps every Left/Right joint pair and reflects x: rotations keep w and their x component and
negate y and z; offsets and positions negate x.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from robot_retarget.array_types import FloatArray
from robot_retarget.skeleton.canonical import CANONICAL_JOINTS, MIRROR_PAIRS


def swap_index(pairs: list[tuple[int, int]], n: int) -> np.ndarray:
    """Index array of ``n`` items with every (left, right) pair of ``pairs`` exchanged."""
    index = np.arange(n)
    for left, right in pairs:
        index[left], index[right] = right, left
    return index


JOINT_MIRROR = swap_index(
    [(CANONICAL_JOINTS.index(a), CANONICAL_JOINTS.index(b)) for a, b in MIRROR_PAIRS],
    len(CANONICAL_JOINTS),
)
_REFLECT_X = np.array([-1.0, 1.0, 1.0])


def mirror_rotations(q: npt.ArrayLike) -> FloatArray:
    """Canonical local rotations (…, 22, 4) of the mirrored pose."""
    m = np.array(np.asarray(q, dtype=np.float64)[..., JOINT_MIRROR, :])
    m[..., 2:] *= -1.0  # a reflection of x keeps w and the x component, negates y and z
    return m


def mirror_offsets(offsets: npt.ArrayLike) -> FloatArray:
    """Rest offsets (22, 3) of the mirrored skeleton (each side takes the other's bones)."""
    return np.asarray(np.asarray(offsets, dtype=np.float64)[JOINT_MIRROR] * _REFLECT_X)


def mirror_points(points: npt.ArrayLike) -> FloatArray:
    """Points (…, 3) reflected in the x = 0 plane (a root path; not joint-indexed)."""
    return np.asarray(np.asarray(points, dtype=np.float64) * _REFLECT_X)
