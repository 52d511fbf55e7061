"""The session facade and its plumbing (events, worker, undo history, session files)."""

from assistant.session.events import EventBus
from assistant.session.session import Session
from assistant.session.types import HiddenObstacle, SessionError, hint_for

__all__ = ["EventBus", "HiddenObstacle", "Session", "SessionError", "hint_for"]
