"""A thin alias kept so the simulator runs from a checkout as ``python -m sim.dxl_bus``.

The simulator is product code and lives in :mod:`robot_retarget.sim`; nothing in the package
imports this folder, and the wheel does not install it.
"""
