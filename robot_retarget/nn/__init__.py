"""Neural retargeting in torch: differentiable rotations, skeleton FK and the networks.

The only package of the library that imports torch. Submodules are imported explicitly
(``from robot_retarget.nn import quaternion_torch``); this file imports none of them, so one
missing or broken submodule never breaks the others.
"""
