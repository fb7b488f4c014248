"""Previews: the human and the robot side by side as stick figures (GIF, or MP4 with ffmpeg)."""

from robot_retarget.render.preview import PreviewError, render_preview

__all__ = ["PreviewError", "render_preview"]
