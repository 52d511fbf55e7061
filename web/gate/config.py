"""What the front is started with, and how its address is shown to people."""

from __future__ import annotations

import ipaddress
import socket
import ssl
from dataclasses import dataclass, field
from pathlib import Path

from web.gate.limits import FailureLimiter
from web.gate.tokens import AccessTokens

LOOPBACK_NAMES = ("localhost", "ip6-localhost")


def is_loopback(host: str) -> bool:
    """True for addresses only this computer can reach (127.0.0.0/8, ::1, localhost)."""
    if host.lower() in LOOPBACK_NAMES:
        return True
    try:
        return ipaddress.ip_address(host.strip("[]")).is_loopback
    except ValueError:
        return False


@dataclass
class GateConfig:
    """The exposed side: address, tokens, TLS and bounds (the upstream is viser on loopback)."""

    host: str
    port: int
    tokens: AccessTokens
    certfile: Path | None = None
    keyfile: Path | None = None
    max_upload_bytes: int = 50 * 2**20
    #: Bodies of HTTP requests (the page only GETs: anything larger is refused unread).
    max_body_bytes: int = 64 * 2**10
    #: One websocket message from a browser (viser sends uploads in 512 KiB parts).
    max_ws_message_bytes: int = 2 * 2**20
    uploads_per_connection: int = 2
    uploads_total: int = 4
    limiter: FailureLimiter = field(default_factory=FailureLimiter)

    @property
    def tls(self) -> bool:
        return self.certfile is not None

    @property
    def exposed(self) -> bool:
        return not is_loopback(self.host)

    def ssl_context(self) -> ssl.SSLContext | None:
        """The server TLS context, or None; a ValueError says which file is wrong."""
        if self.certfile is None:
            if self.keyfile is not None:
                raise ValueError("--keyfile needs --certfile (the certificate it belongs to)")
            return None
        ctx = ssl.create_default_context(ssl.Purpose.CLIENT_AUTH)
        ctx.minimum_version = ssl.TLSVersion.TLSv1_2
        try:
            ctx.load_cert_chain(str(self.certfile),
                                None if self.keyfile is None else str(self.keyfile))
        except FileNotFoundError as exc:
            raise ValueError(f"cannot read {exc.filename}: no such file") from None
        except (ssl.SSLError, OSError) as exc:
            raise ValueError(f"cannot use the certificate {self.certfile} with key "
                             f"{self.keyfile or '(in the certificate file)'}: {exc}") from None
        return ctx


def shown_host(host: str) -> str:
    """The host to put in a printed link: a wildcard bind shows this computer's address."""
    if host in ("0.0.0.0", "::", ""):
        try:  # the address of the interface that routes outwards (no packet is sent)
            with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
                s.connect(("192.0.2.1", 9))
                host = s.getsockname()[0]
        except OSError:
            host = socket.gethostname()
    return f"[{host}]" if ":" in host and not host.startswith("[") else host
