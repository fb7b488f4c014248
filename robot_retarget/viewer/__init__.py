"""Browser viewer (``view``, ``stream --view``): the robot, the performer and joint plots in a
web page served by viser.

viser is an optional dependency (the ``[view]`` extra); only the modules that build a page
import it, lazily, through :func:`robot_retarget.viewer.dependency.require_viser`. The scene
geometry (:mod:`robot_retarget.viewer.scene`) and the playback clock
(:mod:`robot_retarget.viewer.timeline`) are plain numpy and Python.
"""
