"""The robot room's error, below the catalog and the URDF reader that both raise it."""

from __future__ import annotations


class RobotModelError(ValueError):
    """A robot description that cannot be used; the message names the file and the element."""
