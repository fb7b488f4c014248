"""``python -m sim.dxl_bus --robot op3``: forwards to ``python -m robot_retarget.sim.dxl_bus``."""

import sys

from robot_retarget.sim.dxl_bus import main

if __name__ == "__main__":
    sys.exit(main())
