"""The front with real HTTP and websocket clients: nothing without the code, a cookie after the
sign-in form, the way back only to a path on this site, codes never taken from an address nor
logged, wrong codes rate-limited, bodies bounded, TLS with a self-signed certificate made
here, clear messages for a missing certificate and an unsafe token file."""

from __future__ import annotations

import asyncio
import logging
import socket
import ssl
from urllib.parse import urljoin, urlsplit

import aiohttp
import pytest
import websockets
from gate_helpers import (  # noqa: F401
    VISER_PROTOCOL,
    client,
    gated_fixture,
    local_url,
    run,
    self_signed_cert,
    sign_in,
)

from assistant.session import Session
from web.gate import AccessTokens, GateConfig, TokenFileError, is_loopback
from web.gate.banner import UNENCRYPTED, VIEW_ONLY
from web.gate.limits import FailureLimiter
from web.gate.login import CODE_IN_ADDRESS, LOGIN_PATH, WRONG_CODE, safe_path

PATHS = ("/", "/index.html", "/assets/index.js", "/favicon.ico", "/no/such/file",
         "/?darkMode", "/../etc/passwd")
VISER_MARK = b"Viser client"  # in viser's index.html
SIGN_IN = b'action="/_cellteach/login"'


def test_nothing_is_served_without_the_token(gated):
    tokens = AccessTokens.new()
    app = gated(Session(), tokens=tokens)
    url = local_url(app)

    async def go() -> None:
        async with client() as c:
            for path in PATHS:
                for method in ("GET", "HEAD", "POST"):
                    async with c.request(method, url + path, allow_redirects=False) as r:
                        body = await r.read()
                        assert r.status == 401, (method, path, r.status)
                        assert VISER_MARK not in body
                        assert method == "HEAD" or SIGN_IN in body
        for cookie in ("", "wrong-token-of-some-length", tokens.operator + "x"):
            async with client(cookie=cookie) as c:
                async with c.get(url + "/", allow_redirects=False) as r:
                    assert r.status == 401
                with pytest.raises(aiohttp.WSServerHandshakeError) as exc:
                    await c.ws_connect(url, protocols=[VISER_PROTOCOL])
                assert exc.value.status == 401
        # The websocket without any cookie, by a plain websocket client.
        with pytest.raises(websockets.InvalidStatus) as exc:
            async with websockets.connect(url.replace("http", "ws"),
                                          subprotocols=[VISER_PROTOCOL]):
                pass
        assert exc.value.response.status_code == 401

    run(go())


def test_the_sign_in_form_sets_a_cookie_and_goes_back(gated):
    tokens = AccessTokens.new()
    app = gated(Session(), tokens=tokens)
    url = local_url(app)

    async def go() -> None:
        async with client() as c:
            async with c.get(url + "/?darkMode", allow_redirects=False) as r:
                assert r.status == 401 and SIGN_IN in await r.read()
                assert 'name="next" value="/?darkMode"' in await r.text()
            r = await sign_in(c, url, tokens.operator, "/?darkMode")
            assert r.status == 303 and r.headers["Location"] == "/?darkMode"
            cookie = r.headers["Set-Cookie"]
            assert "HttpOnly" in cookie and "SameSite=Lax" in cookie
            assert "Secure" not in cookie  # plain HTTP here (the TLS test checks Secure)
            assert tokens.operator not in r.headers["Location"]
            async with c.get(url + "/") as r:
                assert r.status == 200
                assert VISER_MARK in await r.read()
            # Signed in, the form's address leads back to the page.
            async with c.get(url + LOGIN_PATH + "?next=/x", allow_redirects=False) as r:
                assert r.status == 303 and r.headers["Location"] == "/x"
            # The websocket the page opens carries the cookie and gets viser's stream.
            async with c.ws_connect(url, protocols=[VISER_PROTOCOL]) as ws:
                msg = await ws.receive(timeout=20)
                assert msg.type == aiohttp.WSMsgType.BINARY and len(msg.data) > 16
            # A page of another site may not open it with the operator's cookie.
            with pytest.raises(aiohttp.WSServerHandshakeError) as exc:
                await c.ws_connect(url, protocols=[VISER_PROTOCOL],
                                   headers={"Origin": "http://evil.example"})
            assert exc.value.status == 403

    run(go())


OFF_SITE = ["//evil.example/x", "///evil.example/x", "/\\evil.example/x", "\\evil.example",
            "/\t/evil.example", "https://evil.example/", "http:evil.example",
            "javascript:alert(1)", "evil.example/x", "/\r\nSet-Cookie: a=b", "",
            "//" + "a" * 5000]


@pytest.mark.parametrize("raw", OFF_SITE)
def test_the_way_back_is_only_a_path_on_this_site(raw):
    back = safe_path(raw)
    assert back.startswith("/") and not back.startswith(("//", "/\\"))
    # Wherever a browser resolves it, it stays on this site.
    assert urlsplit(urljoin("http://cell.local:8080/a/b", back)).netloc == "cell.local:8080"
    assert all(0x20 < ord(ch) < 0x7F for ch in back)  # one header-safe token
    assert safe_path("/?darkMode&x=1") == "/?darkMode&x=1"
    assert safe_path("/a b") == "/a%20b"


def test_an_off_site_next_never_becomes_an_off_site_location(gated):
    tokens = AccessTokens.new()
    app = gated(Session(), tokens=tokens)
    url = local_url(app)

    async def go() -> list[str]:
        out = []
        async with client() as c:
            for raw in ("//evil.example/x", "/\\evil.example/x", "https://evil.example/"):
                r = await sign_in(c, url, tokens.viewer, raw)
                assert r.status == 303
                out.append(r.headers["Location"])
        # The reported attack: the page asked as //evil.example/x with the viewer's code.
        async with client() as c, c.get(f"{url}//evil.example/x?token={tokens.viewer}",
                                        allow_redirects=False) as r:
            text = await r.text()
            assert r.status == 401 and "Location" not in r.headers
            assert CODE_IN_ADDRESS in text  # the code in the address was not taken
            assert 'name="next" value="/evil.example/x"' in text
        # Another site's page may not sign a browser in (it could swap the operator's
        # cookie for the viewer's).
        async with client() as other:
            r = await sign_in(other, url, tokens.viewer, "/", Origin="http://evil.example")
            assert r.status == 403 and "Set-Cookie" not in r.headers
        return out

    for location in run(go()):
        assert location.startswith("/") and not location.startswith("//"), location
        assert location in ("/", "/evil.example/x", "/%5Cevil.example/x")


def test_a_code_in_the_address_is_never_taken(gated):
    tokens = AccessTokens.new()
    app = gated(Session(), tokens=tokens)
    url = local_url(app)

    async def go() -> None:
        async with client() as c:
            async with c.get(f"{url}/?token={tokens.operator}", allow_redirects=False) as r:
                assert r.status == 401 and "Set-Cookie" not in r.headers
                text = await r.text()
                assert CODE_IN_ADDRESS in text and tokens.operator not in text
            r = await sign_in(c, url, "not-the-code-but-long-enough")
            assert r.status == 401

    run(go())


def test_viser_behind_the_front_refuses_a_direct_websocket(gated):
    app = gated(Session())
    upstream = f"ws://127.0.0.1:{app.server.get_port()}"

    async def go() -> None:
        async with websockets.connect(upstream, subprotocols=[VISER_PROTOCOL]) as ws:
            with pytest.raises(websockets.ConnectionClosed) as exc:
                while True:
                    await asyncio.wait_for(ws.recv(), 20)
            assert exc.value.rcvd is not None and exc.value.rcvd.code == 1008

    run(go())
    assert app.server.get_clients() == {}


def test_wrong_tokens_are_rate_limited_per_address(gated, caplog, capfd):
    caplog.set_level(logging.DEBUG)
    tokens = AccessTokens.new()
    limiter = FailureLimiter(max_failures=10, window_s=60.0, block_s=300.0)
    app = gated(Session(), tokens=tokens, limiter=limiter)
    url = local_url(app)

    async def go() -> list[int]:
        codes = []
        async with client() as c:
            for i in range(12):
                r = await sign_in(c, url, f"guess{i:020d}")
                codes.append(r.status)
                if r.status == 401:
                    assert WRONG_CODE in await r.text()
            # Blocked: even the right code from this address waits.
            r = await sign_in(c, url, tokens.operator)
            codes.append(r.status)
            assert int(r.headers["Retry-After"]) > 200
        # Another computer (another loopback source address) is not affected.
        async with client(source="127.0.0.2") as c:
            codes.append((await sign_in(c, url, tokens.operator)).status)
        return codes

    codes = run(go())
    assert codes == [401] * 10 + [429] * 3 + [303]
    # The token never reaches a log line or the terminal (only the CLI prints the link).
    out, err = capfd.readouterr()
    text = "\n".join(r.getMessage() for r in caplog.records) + out + err
    assert "blocked 127.0.0.1" in text
    assert tokens.operator not in text and tokens.viewer not in text


def test_request_bodies_are_refused_before_they_are_read(gated):
    app = gated(Session())
    port = app.access.front.port
    with socket.create_connection(("127.0.0.1", port), timeout=10) as s:
        # Announce 1 GB and send none of it: the answer must come at once, unread.
        s.sendall(b"POST / HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Length: 1000000000\r\n\r\n")
        head = s.recv(4096)
    assert head.startswith(b"HTTP/1.1 413")


def test_banner_off_loopback_without_tls_and_for_viewers(gated):
    tokens = AccessTokens.new()
    app = gated(Session(), host="0.0.0.0", tokens=tokens)
    url = local_url(app)
    assert app.access.front.cfg.exposed

    async def page(token: str) -> str:
        async with client() as c:
            await sign_in(c, url, token)
            async with c.get(url + "/") as r:
                assert r.status == 200
                return (await r.read()).decode()

    op, vw = run(page(tokens.operator)), run(page(tokens.viewer))
    assert UNENCRYPTED in op and VIEW_ONLY not in op
    assert UNENCRYPTED in vw and VIEW_ONLY in vw


def test_tls_with_a_self_signed_certificate(gated, tmp_path):
    certfile, keyfile = self_signed_cert(tmp_path)
    tokens = AccessTokens.new()
    app = gated(Session(), host="0.0.0.0", tokens=tokens, certfile=certfile, keyfile=keyfile)
    url = local_url(app)
    assert url.startswith("https://") and app.url.startswith("https://")
    trusting = ssl.create_default_context(cafile=str(certfile))  # verifies host and chain

    async def go() -> None:
        async with client(ssl_ctx=trusting) as c:
            r = await sign_in(c, url, tokens.operator)
            assert r.status == 303 and "Secure" in r.headers["Set-Cookie"]
            async with c.get(url + "/") as r:
                body = await r.read()
                assert r.status == 200 and VISER_MARK in body
                assert UNENCRYPTED.encode() not in body  # encrypted: no warning
            async with c.ws_connect(url, protocols=[VISER_PROTOCOL]) as ws:  # wss://
                msg = await ws.receive(timeout=20)
                assert msg.type == aiohttp.WSMsgType.BINARY
        # Plain HTTP on the TLS port is not served; an untrusting client refuses the cert.
        async with client() as c:
            with pytest.raises(aiohttp.ClientError):
                await c.get(url.replace("https", "http") + "/")
            with pytest.raises(aiohttp.ClientConnectorCertificateError):
                await c.get(url + "/")

    run(go())


def test_bad_certificate_and_token_files_are_named(tmp_path):
    (tmp_path / "junk.pem").write_text("not a certificate")
    cfg = GateConfig("0.0.0.0", 0, AccessTokens.new(), tmp_path / "junk.pem")
    with pytest.raises(ValueError, match="junk.pem.*PEM certificate and its private key"):
        cfg.ssl_context()
    with pytest.raises(ValueError, match=r"cannot read the certificate \(--certfile\) "
                       f"{tmp_path / 'none.pem'}: no such file"):
        GateConfig("0.0.0.0", 0, AccessTokens.new(), tmp_path / "none.pem").ssl_context()
    certfile, _ = self_signed_cert(tmp_path)
    with pytest.raises(ValueError, match=r"cannot read the private key \(--keyfile\) "
                       f"{tmp_path / 'gone.key'}: no such file"):
        GateConfig("0.0.0.0", 0, AccessTokens.new(), certfile, tmp_path / "gone.key"
                   ).ssl_context()
    with pytest.raises(ValueError, match="not a file"):
        GateConfig("0.0.0.0", 0, AccessTokens.new(), tmp_path).ssl_context()
    made = AccessTokens.from_file(tmp_path / "tokens")  # created with new tokens, 0600
    assert (tmp_path / "tokens").stat().st_mode & 0o777 == 0o600
    assert AccessTokens.from_file(tmp_path / "tokens") == made
    (tmp_path / "short").write_text("abc\n")
    (tmp_path / "short").chmod(0o600)
    with pytest.raises(TokenFileError, match="at least 16"):
        AccessTokens.from_file(tmp_path / "short")
    assert is_loopback("127.0.0.1") and is_loopback("::1") and is_loopback("localhost")
    assert not is_loopback("0.0.0.0") and not is_loopback("192.168.1.20")
    assert "<hidden>" in repr(made) and made.operator not in repr(made)


@pytest.mark.parametrize("mode,who", [(0o666, "read and changed"), (0o620, "changed"),
                                      (0o644, "read"), (0o604, "read")])
def test_a_token_file_others_may_read_or_change_is_refused(tmp_path, mode, who):
    path = tmp_path / "tokens"
    made = AccessTokens.from_file(path)
    path.chmod(mode)
    with pytest.raises(TokenFileError, match=f"can be {who} by other users "
                       f"\\(mode {mode:04o}\\).*chmod 600 {path}") as exc:
        AccessTokens.from_file(path)
    assert made.operator not in str(exc.value)
    path.chmod(0o600)
    assert AccessTokens.from_file(path) == made
