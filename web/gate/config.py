"""What the front is started with, and how its address is shown to people."""

from __future__ import annotations

import ipaddress
import socket
import ssl
from dataclasses import dataclass, field
from pathlib import Path

from web.gate.connections import ConnectionLimits
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
    limits: ConnectionLimits = field(default_factory=ConnectionLimits)

    @property
    def tls(self) -> bool:
        return self.certfile is not None

    @property
    def exposed(self) -> bool:
        return not is_loopback(self.host)

    def ssl_context(self) -> ssl.SSLContext | None:
        """The server TLS context, or None; a ValueError says which file is wrong and why."""
        if self.certfile is None:
            if self.keyfile is not None:
                raise ValueError("--keyfile needs --certfile (the certificate it belongs to)")
            return None
        for what, path in (("certificate (--certfile)", self.certfile),
                           ("private key (--keyfile)", self.keyfile)):
            if path is not None:
                _readable(Path(path), what)
        ctx = ssl.create_default_context(ssl.Purpose.CLIENT_AUTH)
        ctx.minimum_version = ssl.TLSVersion.TLSv1_2
        try:
            ctx.load_cert_chain(str(self.certfile),
                                None if self.keyfile is None else str(self.keyfile))
        except (ssl.SSLError, OSError) as exc:
            reason = getattr(exc, "reason", None) or getattr(exc, "strerror", None) or exc
            key = self.keyfile or "(in the certificate file)"
            raise ValueError(f"cannot use the certificate {self.certfile} with the key {key}: "
                             f"{reason} - give a PEM certificate and its private key "
                             "(--keyfile if the key is in a file of its own)") from None
        return ctx


def _readable(path: Path, what: str) -> None:
    """ValueError naming `path` if it cannot be read as a file."""
    if not path.exists():
        raise ValueError(f"cannot read the {what} {path}: no such file")
    if not path.is_file():
        raise ValueError(f"cannot read the {what} {path}: not a file")
    try:
        with open(path, "rb") as f:
            f.read(1)
    except OSError as exc:
        raise ValueError(f"cannot read the {what} {path}: {exc.strerror or exc}") from None


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
