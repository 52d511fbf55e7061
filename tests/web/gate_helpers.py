"""The gated page for tests: a real `web.serve(..., gate=...)`, real HTTP/websocket clients
(aiohttp) and viser's own wire format for the messages a browser sends."""

from __future__ import annotations

import asyncio
import contextlib
import datetime
import ipaddress
import ssl
import threading
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import aiohttp
import msgspec
import pytest

from web.gate import AccessTokens, GateConfig
from web.gate.login import LOGIN_PATH

VISER_PROTOCOL = "viser-v" + __import__("viser").__version__
#: What viser's client sends first: a camera (viser counts a client as connected after it).
CAMERA = {"type": "ViewerCameraMessage", "wxyz": [1.0, 0.0, 0.0, 0.0],
          "position": [1.0, 1.0, 1.0], "fov": 1.0, "near": 0.01, "far": 100.0,
          "image_height": 600, "image_width": 800, "look_at": [0.0, 0.0, 0.0],
          "up_direction": [0.0, 0.0, 1.0]}


def encode(msg: dict[str, Any]) -> bytes:
    return msgspec.msgpack.encode(msg)


def click(uuid: str) -> bytes:
    """A button press exactly as viser's client sends it (components/Button.tsx)."""
    return encode({"type": "GuiUpdateMessage", "uuid": uuid, "updates": {"value": True}})


def uuid_of(handle: Any) -> str:
    return handle._impl.uuid  # noqa: SLF001 - the id the browser knows the control by


@pytest.fixture(name="gated")
def gated_fixture() -> Iterator[Callable[..., Any]]:
    """Start the page behind the gate (loopback unless `host` is given); stopped afterwards."""
    from web import serve

    apps: list[Any] = []

    def start(session: Any, *, host: str = "127.0.0.1", tokens: AccessTokens | None = None,
              max_upload_mb: float = 50.0, **cfg: Any) -> Any:
        gate = GateConfig(host, 0, tokens or AccessTokens.new(), **cfg)
        app = serve(session, gate=gate, max_upload_mb=max_upload_mb)
        apps.append(app)
        return app

    yield start
    for app in apps:
        app.stop()


def local_url(app: Any) -> str:
    """The front's address as this computer reaches it (also when bound to 0.0.0.0)."""
    return f"{app.access.front.scheme}://127.0.0.1:{app.access.front.port}"


def client(*, cookie: str | None = None, source: str | None = None,
           ssl_ctx: ssl.SSLContext | None = None) -> aiohttp.ClientSession:
    """A fresh HTTP client (cookies kept also for an IP address), optionally from another
    loopback source address (127.0.0.2: another "computer" for the rate limit)."""
    conn = aiohttp.TCPConnector(local_addr=(source, 0) if source else None,
                                ssl=ssl_ctx if ssl_ctx is not None else True)
    jar = aiohttp.CookieJar(unsafe=True)
    s = aiohttp.ClientSession(connector=conn, cookie_jar=jar)
    if cookie is not None:
        s.cookie_jar.update_cookies({"cellteach_access": cookie})
    return s


async def sign_in(c: aiohttp.ClientSession, url: str, code: str, next_path: str = "/",
                  **headers: str) -> aiohttp.ClientResponse:
    """Send the sign-in form as a browser does (not following the redirect); the response
    (already read: status, headers) - its cookie stays in `c`'s jar."""
    async with c.post(url + LOGIN_PATH, data={"code": code, "next": next_path},
                      allow_redirects=False, headers=headers) as r:
        await r.read()
        return r


async def wait_for(pred: Callable[[], bool], timeout: float = 20.0) -> bool:
    """Until pred() holds (polls the in-process app; False on timeout)."""
    loop = asyncio.get_running_loop()
    end = loop.time() + timeout
    while loop.time() < end:
        if pred():
            return True
        await asyncio.sleep(0.05)
    return pred()


def run(coro: Any) -> Any:
    """Run a client coroutine to its end on its own thread and event loop: the browser tests'
    Playwright (sync API) keeps an event loop running in the test thread, where asyncio.run
    refuses to start another."""
    out: dict[str, Any] = {}

    def main() -> None:
        try:
            out["value"] = asyncio.run(coro)
        except BaseException as exc:  # noqa: BLE001 - re-raised in the test's thread
            out["error"] = exc

    t = threading.Thread(target=main, name="gate-client", daemon=True)
    t.start()
    t.join()
    if "error" in out:
        raise out["error"]
    return out.get("value")


class Page:
    """One browser as the front sees it: its HTTP client (from `source`, another loopback
    address: another computer), websocket, viser client id and every message it received."""

    def __init__(self, app: Any, token: str, source: str | None = None):
        self.app, self.token, self.source = app, token, source
        self.received: list[bytes] = []
        self.http: aiohttp.ClientSession | None = None
        self.ws: aiohttp.ClientWebSocketResponse | None = None
        self.client_id: int | None = None
        self._drain: asyncio.Task | None = None

    async def __aenter__(self) -> Page:
        url = local_url(self.app)
        before = set(self.app.server.get_clients())
        self.http = client(source=self.source)
        assert (await sign_in(self.http, url, self.token)).status == 303
        self.ws = await self.http.ws_connect(url, protocols=[VISER_PROTOCOL])
        self._drain = asyncio.ensure_future(self._read())
        await self.ws.send_bytes(encode(CAMERA))  # a camera passes for every role
        assert await wait_for(lambda: set(self.app.server.get_clients()) - before)
        (self.client_id,) = set(self.app.server.get_clients()) - before
        return self

    async def _read(self) -> None:
        async for msg in self.ws:  # keep the stream flowing
            if msg.type == aiohttp.WSMsgType.BINARY:
                self.received.append(unpack_frame(msg.data))

    def saw(self, text: str) -> bool:
        """Whether any message this page received holds `text` (in the msgpack that
        `unpack_frame` opened, strings are UTF-8 bytes)."""
        needle = text.encode()
        return any(needle in m for m in self.received)

    @property
    def client(self) -> Any:
        return self.app.server.get_clients()[self.client_id]

    async def send(self, raw: bytes) -> None:
        await self.ws.send_bytes(raw)

    async def __aexit__(self, *exc: Any) -> None:
        with contextlib.suppress(Exception):
            await self.ws.close()
        if self._drain is not None:
            self._drain.cancel()
        await self.http.close()


def unpack_frame(raw: bytes) -> bytes:
    """One websocket frame from viser as its page reads it: viser 1.1 sends [8 bytes
    msgpack size][8 bytes compressed size][zstd(msgpack)][binary arrays]; the msgpack
    (decompressed) and the arrays."""
    import zstandard

    size = int.from_bytes(raw[:8], "little")
    packed = int.from_bytes(raw[8:16], "little")
    inner = zstandard.ZstdDecompressor().decompress(raw[16:16 + packed],
                                                    max_output_size=size)
    assert len(inner) == size, "not viser's wire format"
    return inner + raw[16 + packed:]


def self_signed_cert(tmp: Path) -> tuple[Path, Path]:
    """A certificate for 127.0.0.1 and its key, made here (PEM files in `tmp`)."""
    from cryptography import x509
    from cryptography.hazmat.primitives import hashes, serialization
    from cryptography.hazmat.primitives.asymmetric import ec
    from cryptography.x509.oid import NameOID

    key = ec.generate_private_key(ec.SECP256R1())
    name = x509.Name([x509.NameAttribute(NameOID.COMMON_NAME, "cellteach test")])
    now = datetime.datetime.now(datetime.timezone.utc)
    cert = (x509.CertificateBuilder().subject_name(name).issuer_name(name)
            .public_key(key.public_key()).serial_number(x509.random_serial_number())
            .not_valid_before(now - datetime.timedelta(minutes=5))
            .not_valid_after(now + datetime.timedelta(days=1))
            .add_extension(x509.SubjectAlternativeName(
                [x509.IPAddress(ipaddress.ip_address("127.0.0.1"))]), critical=False)
            .sign(key, hashes.SHA256()))
    certfile, keyfile = tmp / "cert.pem", tmp / "key.pem"
    certfile.write_bytes(cert.public_bytes(serialization.Encoding.PEM))
    keyfile.write_bytes(key.private_bytes(serialization.Encoding.PEM,
                                          serialization.PrivateFormat.PKCS8,
                                          serialization.NoEncryption()))
    return certfile, keyfile
