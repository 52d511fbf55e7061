"""The controller's login for the RWS emulator: HTTP digest (RFC 2617, MD5, qop=auth) on an
IRC5, HTTP Basic on an OmniCore, then a session cookie, and single mastership per session.

A request without a valid session cookie gets ``401`` with a ``WWW-Authenticate: Digest``
challenge (realm ``validusers@robapi.abb`` as on the controller); a valid digest answer opens
a session and sets the ``-http-session-`` and ``ABBCX`` cookies. Both `requests` (what
abb-robot-client uses, which re-sends digest headers pre-emptively) and `urllib` (our link,
which relies on the cookie) get through; a wrong password never does.
"""

from __future__ import annotations

import base64
import hashlib
import secrets
import threading
from dataclasses import dataclass
from http.cookies import SimpleCookie
from urllib.request import parse_http_list, parse_keqv_list

REALM = "validusers@robapi.abb"
SESSION_COOKIE = "-http-session-"


def _md5(text: str) -> str:
    return hashlib.md5(text.encode("utf-8")).hexdigest()


@dataclass
class Session:
    sid: str
    user: str
    abbcx: str


class DigestSessions:
    """Users, issued nonces, open sessions and the mastership holder (all under one lock)."""

    def __init__(self, users: dict[str, str], *, basic: bool = False):
        self.users = dict(users)
        #: RWS 2.0 (OmniCore) logins are HTTP Basic (over TLS); 1.0 ones digest.
        self.basic = basic
        self._nonces: set[str] = set()
        self._sessions: dict[str, Session] = {}
        self._lock = threading.Lock()
        self.opaque = secrets.token_hex(8)
        self.master: str | None = None  # session id holding mastership

    def challenge(self) -> str:
        if self.basic:
            return f'Basic realm="{REALM}"'
        nonce = secrets.token_hex(16)
        with self._lock:
            self._nonces.add(nonce)
        return (f'Digest realm="{REALM}", qop="auth", nonce="{nonce}", '
                f'opaque="{self.opaque}", algorithm=MD5')

    def authenticate(self, method: str, path: str, headers) -> tuple[Session | None, bool]:
        """(session, new): from the cookie, else from a valid digest Authorization."""
        cookie = SimpleCookie()
        try:
            cookie.load(headers.get("Cookie", ""))
        except Exception:  # noqa: BLE001 - a malformed cookie is just no session
            cookie = SimpleCookie()
        if SESSION_COOKIE in cookie:
            with self._lock:
                s = self._sessions.get(cookie[SESSION_COOKIE].value)
            if s is not None:
                return s, False
        header = headers.get("Authorization", "")
        user = self._basic_user(header) if self.basic else \
            self._digest_user(method, path, header)
        if user is None:
            return None, False
        s = Session(secrets.token_hex(12), user, secrets.token_hex(8))
        with self._lock:
            self._sessions[s.sid] = s
        return s, True

    def _basic_user(self, header: str) -> str | None:
        if not header.lower().startswith("basic "):
            return None
        try:
            user, _, pw = base64.b64decode(header[6:].strip()).decode("utf-8").partition(":")
        except (ValueError, UnicodeDecodeError):
            return None
        ok = user in self.users and secrets.compare_digest(pw, self.users[user])
        return user if ok else None

    def _digest_user(self, method: str, path: str, header: str) -> str | None:
        if not header.lower().startswith("digest "):
            return None
        try:
            p = parse_keqv_list(parse_http_list(header[7:]))
        except ValueError:
            return None
        user = p.get("username", "")
        with self._lock:
            known_nonce = p.get("nonce") in self._nonces
        if user not in self.users or not known_nonce or p.get("uri") != path:
            return None
        ha1 = _md5(f"{user}:{REALM}:{self.users[user]}")
        ha2 = _md5(f"{method}:{p['uri']}")
        if p.get("qop") == "auth":
            want = _md5(f"{ha1}:{p['nonce']}:{p.get('nc', '')}:{p.get('cnonce', '')}:auth:{ha2}")
        else:
            want = _md5(f"{ha1}:{p['nonce']}:{ha2}")
        return user if secrets.compare_digest(want, p.get("response", "")) else None

    @staticmethod
    def cookies(s: Session) -> list[str]:
        return [f"{SESSION_COOKIE}={s.sid}; Path=/; HttpOnly", f"ABBCX={s.abbcx}; Path=/"]

    def logout(self, s: Session) -> None:
        with self._lock:
            self._sessions.pop(s.sid, None)
            if self.master == s.sid:
                self.master = None

    def forget_all(self) -> None:
        """A controller restart / cable pull: every session and the mastership are gone."""
        with self._lock:
            self._sessions.clear()
            self.master = None

    # ------------------------------------------------------------------ mastership
    def request_mastership(self, s: Session) -> bool:
        with self._lock:
            if self.master not in (None, s.sid):
                return False
            self.master = s.sid
            return True

    def release_mastership(self, s: Session) -> bool:
        with self._lock:
            if self.master not in (None, s.sid):
                return False
            self.master = None
            return True

    def held_by_other(self, s: Session) -> bool:
        with self._lock:
            return self.master not in (None, s.sid)

    def holds(self, s: Session) -> bool:
        with self._lock:
            return self.master == s.sid
