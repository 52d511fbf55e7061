"""The session facade and its plumbing: `Session` (state, action plumbing, workflow) mixing in
one part per concern (set-up, cell, teach, motion, planning, scene, export, persistence), its
events, worker thread, undo history, session files and YAML scripts.

May import every room of the assistant below it, `workflow` and `vision`; never `web` or viser.
"""

from assistant.session.events import EventBus
from assistant.session.session import Session
from assistant.session.types import HiddenObstacle, SessionError, hint_for

__all__ = ["EventBus", "HiddenObstacle", "Session", "SessionError", "hint_for"]
