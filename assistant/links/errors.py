"""Link failures that carry what the peer said, so the operator sees the controller's words."""

from __future__ import annotations

from assistant.links.link import LinkError


class ControllerRefused(LinkError):
    """The controller answered but refused the command: its error code and the raw reply."""

    def __init__(self, message: str, *, code: str, raw: str):
        super().__init__(message)
        self.code = code
        self.raw = raw


class ProtocolError(LinkError):
    """The peer answered something outside the protocol; the message quotes the raw reply."""

    def __init__(self, message: str, *, raw: str):
        super().__init__(message)
        self.raw = raw
