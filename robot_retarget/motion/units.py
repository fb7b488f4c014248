"""Length units of motion files, and telling them apart from a skeleton's standing height.

BVH files carry no unit. A person is 1.4–2.0 m tall, so the unit whose scale puts the
skeleton's standing height nearest to an adult's (1.7 m, compared on a log scale) is the unit
the file was written in. Candidate scales are far enough apart (≥ ×2.2) for this to be
unambiguous for adults and older children.
"""

from __future__ import annotations

import math

from robot_retarget.errors import MotionFormatError

# CMU ASF length unit: the CMU FAQ gives 1 unit = (1/0.45) inch = 5.644 cm.
CMU_UNIT_M = (1.0 / 0.45) * 0.0254

UNIT_SCALES_M: dict[str, float] = {
    "m": 1.0,
    "cm": 0.01,
    "mm": 0.001,
    "inch": 0.0254,
    "cmu": CMU_UNIT_M,
}

_TYPICAL_HEIGHT_M = 1.7
PLAUSIBLE_HEIGHT_M = (0.25, 5.0)  # what auto-detection accepts as a performer's height


def unit_scale_m(unit: str) -> float:
    """Metres per file unit for a unit name (one of UNIT_SCALES_M)."""
    try:
        return UNIT_SCALES_M[unit]
    except KeyError:
        raise MotionFormatError(
            f"unknown length unit {unit!r}; use one of {', '.join(UNIT_SCALES_M)}"
        ) from None


def detect_unit(height_file_units: float, path: str | None = None) -> str:
    """The unit that makes a standing height (in file units) most like an adult's; ``path``
    names the file in the error when no unit makes it a performer's."""
    if not (math.isfinite(height_file_units) and height_file_units > 0.0):
        raise MotionFormatError(
            f"cannot detect the length unit from a standing height of {height_file_units}; "
            "pass the unit explicitly",
            path=path,
        )
    unit = min(
        UNIT_SCALES_M,
        key=lambda u: abs(math.log(height_file_units * UNIT_SCALES_M[u] / _TYPICAL_HEIGHT_M)),
    )
    height_m = height_file_units * UNIT_SCALES_M[unit]
    if not PLAUSIBLE_HEIGHT_M[0] <= height_m <= PLAUSIBLE_HEIGHT_M[1]:
        raise MotionFormatError(
            f"the skeleton stands {height_file_units:.3g} file units tall, {height_m:.3g} m "
            f"even in {unit}, the likeliest unit: no unit makes it a performer "
            f"({PLAUSIBLE_HEIGHT_M[0]:g}–{PLAUSIBLE_HEIGHT_M[1]:g} m); are the OFFSETs right?",
            path=path,
        )
    return unit
