"""The upload size limit: refuse early (the browser announces the size before sending the
bytes) and check again when the file is complete, with a message that says what to do.

viser 1.1 has no upload limit of its own. The early check listens to the same "upload
starts" message viser handles and drops the transfer's buffer, so a 2 GB file cannot fill
the server's memory; it relies on viser internals and is skipped if they change - the check
on the complete file always runs.
"""

from __future__ import annotations

import logging
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from web.app import App

log = logging.getLogger(__name__)

#: The upload limit unless the server is started with another (--max-upload-mb): a binary
#: STL of the 4 000 000 triangles a CAD import takes is 191 MB.
DEFAULT_MAX_UPLOAD_MB = 200


class UploadTooLarge(ValueError):
    pass


def too_large_message(name: str, nbytes: int, limit: int) -> str:
    return (f"{name} is {nbytes / 2**20:.1f} MB; this page accepts files up to "
            f"{limit / 2**20:.0f} MB. Simplify or decimate the part in CAD, or restart the "
            f"server with a larger --max-upload-mb.")


def check_upload_size(app: App, name: str, nbytes: int) -> None:
    if nbytes > app.max_upload_bytes:
        raise UploadTooLarge(too_large_message(name, nbytes, app.max_upload_bytes))


def install_early_limit(app: App) -> bool:
    """Refuse an oversized upload as soon as it starts; False if viser's internals moved."""
    try:
        from viser import _messages

        ws = app.server._websock_server  # noqa: SLF001
        gui = app.server.gui
        states: dict[str, Any] = gui._current_file_upload_states  # noqa: SLF001
    except Exception:  # noqa: BLE001
        log.info("viser internals changed: upload size checked after the transfer only")
        return False

    def on_start(client_id: int, message: Any) -> None:
        if message.size_bytes <= app.max_upload_bytes:
            return
        states.pop(message.transfer_uuid, None)  # later parts are ignored by viser
        # Tell the browser the transfer is over so its upload button works again.
        ws.queue_message(_messages.FileTransferPartAck(
            source_component_uuid=message.source_component_uuid,
            transfer_uuid=message.transfer_uuid, transferred_bytes=message.size_bytes,
            total_bytes=message.size_bytes))
        client = app.server.get_clients().get(client_id)
        app.notifier.error(too_large_message(message.filename, message.size_bytes,
                                             app.max_upload_bytes), client=client)

    ws.register_handler(_messages.FileTransferStartUpload, on_start)
    return True
