"""The little of RFC 6455 (WebSocket) an RWS subscription needs, client and server side.

ABB's Robot Web Services push subscribed events (execution state, event log) over a
websocket (subprotocol ``robapi2_subscription`` on RWS 1.0, ``rws_subscription`` on 2.0).
The link reads text frames from a thread; the emulator writes them. Every read has a
deadline; a frame larger than `MAX_FRAME` or a bad handshake is a `WebSocketError`.
"""

from __future__ import annotations

import base64
import hashlib
import os
import socket
import ssl
import struct
from urllib.parse import urlsplit

GUID = "258EAFA5-E914-47DA-95CA-C5AB0DC85B11"
MAX_FRAME = 1 << 20
OP_TEXT, OP_CLOSE, OP_PING, OP_PONG = 0x1, 0x8, 0x9, 0xA


class WebSocketError(OSError):
    """The peer broke the websocket protocol or closed the connection."""


def accept_key(key: str) -> str:
    return base64.b64encode(hashlib.sha1((key + GUID).encode()).digest()).decode()


def frame(payload: bytes, opcode: int = OP_TEXT, mask: bool = False) -> bytes:
    """One final frame; clients must mask (RFC 6455 5.3), servers must not."""
    n = len(payload)
    head = bytes([0x80 | opcode])
    bit = 0x80 if mask else 0
    if n < 126:
        head += bytes([bit | n])
    elif n < 1 << 16:
        head += bytes([bit | 126]) + struct.pack(">H", n)
    else:
        head += bytes([bit | 127]) + struct.pack(">Q", n)
    if not mask:
        return head + payload
    key = os.urandom(4)
    return head + key + bytes(b ^ key[i % 4] for i, b in enumerate(payload))


def _exact(sock: socket.socket, n: int) -> bytes:
    buf = b""
    while len(buf) < n:
        chunk = sock.recv(n - len(buf))
        if not chunk:
            raise WebSocketError("the peer closed the websocket")
        buf += chunk
    return buf


def read_frame(sock: socket.socket) -> tuple[int, bytes]:
    """(opcode, payload) of the next frame (masked or not); fragments are not used by RWS."""
    b0, b1 = _exact(sock, 2)
    n = b1 & 0x7F
    if n == 126:
        (n,) = struct.unpack(">H", _exact(sock, 2))
    elif n == 127:
        (n,) = struct.unpack(">Q", _exact(sock, 8))
    if n > MAX_FRAME:
        raise WebSocketError(f"websocket frame of {n} bytes")
    key = _exact(sock, 4) if b1 & 0x80 else b""
    data = _exact(sock, n)
    if key:
        data = bytes(b ^ key[i % 4] for i, b in enumerate(data))
    return b0 & 0x0F, data


def connect(url: str, *, subprotocol: str, headers: dict[str, str], timeout_s: float,
            tls: ssl.SSLContext | None = None) -> socket.socket:
    """Open ``ws://`` / ``wss://`` `url`; returns the socket after a checked handshake."""
    u = urlsplit(url)
    secure = u.scheme == "wss"
    port = u.port or (443 if secure else 80)
    sock = socket.create_connection((u.hostname, port), timeout_s)
    if secure:
        sock = (tls or ssl.create_default_context()).wrap_socket(sock,
                                                                 server_hostname=u.hostname)
    sock.settimeout(timeout_s)
    key = base64.b64encode(os.urandom(16)).decode()
    lines = [f"GET {u.path or '/'}{'?' + u.query if u.query else ''} HTTP/1.1",
             f"Host: {u.hostname}:{port}", "Upgrade: websocket", "Connection: Upgrade",
             f"Sec-WebSocket-Key: {key}", "Sec-WebSocket-Version: 13",
             f"Sec-WebSocket-Protocol: {subprotocol}"]
    lines += [f"{k}: {v}" for k, v in headers.items()]
    sock.sendall(("\r\n".join(lines) + "\r\n\r\n").encode())
    head = b""
    while b"\r\n\r\n" not in head:
        chunk = sock.recv(4096)
        if not chunk:
            sock.close()
            raise WebSocketError("the server closed the connection during the handshake")
        head += chunk
        if len(head) > 65536:
            sock.close()
            raise WebSocketError("websocket handshake reply too long")
    text = head.split(b"\r\n\r\n", 1)[0].decode("latin-1")
    status = text.split("\r\n", 1)[0]
    fields = {k.strip().lower(): v.strip() for k, _, v in
              (ln.partition(":") for ln in text.split("\r\n")[1:])}
    if " 101 " not in status + " " or fields.get("sec-websocket-accept") != accept_key(key):
        sock.close()
        raise WebSocketError(f"websocket handshake refused: {status!r}")
    return sock
