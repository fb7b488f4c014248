"""What the foot lock (``robot_retarget.nn.models.foot_lock``, and its compiled twin
``robot_retarget.runtime.foot_lock_graph``) works on and with: the legs, the soft contact
test's ramps and the IK's margins. Torch-free, so the live path reads it without torch."""

from __future__ import annotations

from robot_retarget.skeleton.canonical import Joint

# (hip, knee, ankle) joints per leg: LeftUpLeg's rotation orients the thigh, and so on.
LEGS: tuple[tuple[int, int, int], ...] = (
    (Joint.LeftUpLeg, Joint.LeftLeg, Joint.LeftFoot),
    (Joint.RightUpLeg, Joint.RightLeg, Joint.RightFoot),
)
ANKLES: list[int] = [ankle for _, _, ankle in LEGS]
CONTACT_FPS = 30.0  # the rate speeds are judged at: the models' training and evaluation rate
# The contact test's thresholds ± these fractions ramp a contact's weight from 1 to 0.
SPEED_RAMP = 1.0 / 6.0
HEIGHT_RAMP = 0.2
# Law-of-cosines margins: a fully stretched leg keeps a hair of bend, so angles stay smooth.
STRETCH = 1e-4
COS_MARGIN = 1e-4
KNEE_AXIS = (1.0, 0.0, 0.0)  # canonical rest frames: X points left, the knee's hinge
# The knee axis joins the thigh × shin normal with this weight (× both lengths): it decides the
# bend of a straight leg, and tilts a bent knee's axis out of the leg's plane by at most
# 1e-5 / sin(bend) rad (0.02° at a 2° bend).
HINGE_WEIGHT = 1e-5
