"""Input corruption for the denoising test (SAN's protocol, numpy only).

SAN adds white noise of σ = 0.01 × height and random zeros to the input and compares the
output with the output for clean input. Our models read rotations and a root position, so:

- the root position gets Gaussian noise of σ = ``sigma_frac`` × height (metres);
- every non-root joint rotation gets a random rotation whose rotation-vector components have
  σ = ``sigma_frac`` × 6 rad — a bone of a sixth of the height (a typical limb segment) then
  moves its end by ≈ σ_frac × height, the same positional noise;
- each non-root joint rotation is replaced by the identity ("zeroed") with probability
  ``zero_prob``.

The root rotation is left clean: it carries the heading, whose per-frame noise would integrate
into a random walk of the whole trajectory and swamp every other difference.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from robot_retarget.array_types import FloatArray
from robot_retarget.geometry import quaternion as quat

NOISE_SIGMA_FRAC = 0.01
ZERO_PROB = 0.02
# Typical segment length as a fraction of height: turns positional noise into angular noise.
_SEGMENT_FRAC = 1.0 / 6.0


def corrupt(
    local_quats: npt.ArrayLike,
    root_pos: npt.ArrayLike,
    height_m: float,
    rng: np.random.Generator,
    *,
    sigma_frac: float = NOISE_SIGMA_FRAC,
    zero_prob: float = ZERO_PROB,
) -> tuple[FloatArray, FloatArray]:
    """Noisy copies of rotations (T, J, 4) and root positions (T, 3) (see module docstring)."""
    q = quat.as_float_array(local_quats)
    root = np.asarray(root_pos, dtype=np.float64)
    sigma_rad = sigma_frac / _SEGMENT_FRAC
    noise = quat.from_rotation_vector(rng.normal(0.0, sigma_rad, size=(*q.shape[:-1], 3)))
    noisy = quat.mul(q, noise)
    zeroed = rng.random(q.shape[:-1]) < zero_prob
    noisy = np.where(zeroed[..., None], quat.identity(()), noisy)
    noisy[..., 0, :] = q[..., 0, :]
    noisy_root = root + rng.normal(0.0, sigma_frac * height_m, size=root.shape)
    return quat.make_continuous(quat.normalize(noisy), axis=0), noisy_root
