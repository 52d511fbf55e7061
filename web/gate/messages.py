"""What a browser may send up the websocket, by role: viser's client -> server message types.

viser's client sends msgpack maps with a "type" key (uncompressed). A viewer may send only
what a read-only page needs: its own camera (viser counts a client as connected after its first
camera message) and the answers to the server's own requests. Everything else changes shared
state and is dropped. The share-tunnel requests are dropped for everyone: a tunnel would
publish the loopback viser to the internet around the front.

Uploads are counted here too: at most `uploads_per_connection` in flight per browser and
`UploadSlots.total` over the front, and no transfer may send more bytes than it announced or
than the page accepts (the app refuses an oversized start with its message; its parts are then
dropped here unread by viser).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import msgspec

from web.gate.limits import UploadSlots
from web.gate.tokens import Role

#: Client -> server messages a viewer may send (see the module docstring).
VIEWER_MAY_SEND = frozenset({
    "ViewerCameraMessage", "GetRenderResponseMessage", "LocalStorageGetItemResponseMessage"})
#: Never passed, whoever sends them.
NOBODY_MAY_SEND = frozenset({"ShareUrlRequest", "ShareUrlDisconnect"})
#: What viser's 1.1 client sends that changes shared state (documented; tests send each).
CHANGING = ("GuiUpdateMessage", "GuiButtonHoldMessage", "GuiFormSubmitMessage",
            "GuiFormDirtyMessage", "CommandTriggerMessage", "FileTransferStartUpload",
            "FileTransferPart", "SceneNodeClickMessage", "SceneNodeDragMessage",
            "ScenePointerMessage", "TransformControlsUpdateMessage",
            "TransformControlsDragStartMessage", "TransformControlsDragEndMessage")


class CloseConnection(Exception):
    """The browser broke a bound: its websocket is closed with this reason."""


@dataclass
class _Transfer:
    parts_left: int
    bytes_left: int
    dropped: bool


@dataclass
class MessageGuard:
    """One browser connection's filter: `admit(raw)` -> forward it or not."""

    role: Role
    slots: UploadSlots
    max_upload_bytes: int
    uploads_per_connection: int = 2
    dropped: int = 0
    _transfers: dict[str, _Transfer] = field(default_factory=dict)

    def admit(self, raw: bytes) -> bool:
        try:
            msg = msgspec.msgpack.decode(raw)
            kind = msg["type"]
        except (msgspec.DecodeError, KeyError, TypeError):
            raise CloseConnection("not a viser message") from None
        if kind in NOBODY_MAY_SEND or (self.role != Role.OPERATOR and
                                       kind not in VIEWER_MAY_SEND):
            self.dropped += 1
            return False
        if kind == "FileTransferStartUpload":
            return self._start(msg)
        if kind == "FileTransferPart" and msg.get("source_component_uuid") is not None:
            return self._part(msg)
        return True

    def _start(self, msg: dict[str, Any]) -> bool:
        uuid, size = str(msg.get("transfer_uuid")), int(msg.get("size_bytes", 0))
        if uuid in self._transfers:
            raise CloseConnection("an upload was started twice")
        live = sum(not t.dropped for t in self._transfers.values())
        if live >= self.uploads_per_connection or not self.slots.take():
            raise CloseConnection("too many uploads at once: wait for one to finish")
        # Over the limit: the start still goes up (the app tells the operator the limit and
        # ends the transfer in the browser); its parts stop here.
        dropped = size > self.max_upload_bytes or size < 0
        if dropped:
            self.slots.give()
        self._transfers[uuid] = _Transfer(int(msg.get("part_count", 0)), max(size, 0), dropped)
        return True

    def _part(self, msg: dict[str, Any]) -> bool:
        t = self._transfers.get(str(msg.get("transfer_uuid")))
        if t is None:
            self.dropped += 1
            return False
        n = len(msg.get("content") or b"")
        t.parts_left -= 1
        t.bytes_left -= n
        if t.dropped:
            if t.parts_left <= 0:
                self._transfers.pop(str(msg["transfer_uuid"]))
            self.dropped += 1
            return False
        if t.bytes_left < 0 or t.parts_left < 0:
            raise CloseConnection("an upload sent more than it announced")
        if t.parts_left == 0:
            self._transfers.pop(str(msg["transfer_uuid"]))
            self.slots.give()
        return True

    def close(self) -> None:
        """The connection ended: its uploads in flight give their slots back."""
        self.slots.give(sum(not t.dropped for t in self._transfers.values()))
        self._transfers.clear()
