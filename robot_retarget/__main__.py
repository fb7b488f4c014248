"""``python -m robot_retarget``: the ``robot-retarget`` command."""

from robot_retarget.cli.main import main

raise SystemExit(main())
