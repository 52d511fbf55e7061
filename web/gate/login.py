"""Signing in: the access code goes in a form, never in an address, and the way back is only
ever a path on this site.

Why a form: a browser keeps every address it opened in its history - Chromium 156 keeps
`/?token=...` after a 303 redirect, after `history.replaceState`, and `/#token=...` after a
script exchanged the fragment and replaced the page (tests/web/test_gate_browser.py reads its
History database). Only an address that never held the code keeps it out. So, as code-server
does (and JupyterHub 5, which refuses tokens in URLs by default), the page asks for the code
and POSTs it; the answer sets the HttpOnly cookie and sends the browser back where it wanted
to go. The form is served only by the front and carries no script.

Why only a path: the way back comes from the address the browser asked for, so an attacker
could ask for `//evil.example/x` (a "path" a browser reads as another site) - as Jupyter
Server's `_redirect_safe` does, `safe_path` keeps a single leading slash, turns backslashes
(which browsers read as slashes) into `%5C` and drops anything with a scheme or a host.
"""

from __future__ import annotations

import html
from urllib.parse import quote, urlsplit

LOGIN_PATH = "/_cellteach/login"
#: Path and query characters left as they are in the way back (the rest is %-encoded).
_SAFE = "/:@!$&'()*+,;=-._~%?"
#: The longest way back kept (a longer one is replaced by "/").
MAX_NEXT = 2048

TITLE = "cellteach: enter the access code"
CODE_IN_ADDRESS = "Access codes are not taken from the address: the browser would keep them " \
    "in its history. Paste the code below instead (and clear this address from the " \
    "history if others use this browser)."
WRONG_CODE = "That access code is not right."


def safe_path(raw: str | None) -> str:
    """A same-site path (with its query) to go back to; "/" for anything else."""
    if not raw or len(raw) > MAX_NEXT or any(ord(c) < 0x20 or ord(c) == 0x7F for c in raw):
        return "/"
    raw = raw.replace("\\", "%5C")
    parts = urlsplit(raw)
    if parts.scheme or parts.netloc or not parts.path.startswith("/"):
        return "/"
    path = "/" + parts.path.lstrip("/")  # "//evil.example" would leave the site
    query = f"?{parts.query}" if parts.query else ""
    return quote(path + query, safe=_SAFE)


def login_page(next_path: str, *, message: str = "", unencrypted: bool = False) -> str:
    """The sign-in page: one password field (the browser may save the code), no script."""
    warn = ('<p style="color:#b3261e">Not encrypted: anyone on this network can read what '
            "you send here.</p>") if unencrypted else ""
    note = f'<p role="alert" style="color:#b3261e"><b>{html.escape(message)}</b></p>' \
        if message else ""
    return f"""<!doctype html><html lang="en"><head><meta charset="utf-8">
<meta name="viewport" content="width=device-width, initial-scale=1"><title>{TITLE}</title>
</head><body style="font-family:sans-serif;max-width:34em;margin:3em auto;padding:0 1em">
<h1 style="font-size:1.4em">This cellteach page needs its access code</h1>{note}
<p>The person who started the assistant has two codes: the operator code (drives the page
and the robot) and the viewer code (watches only). Paste yours here.</p>{warn}
<form method="post" action="{LOGIN_PATH}">
<input type="hidden" name="next" value="{html.escape(safe_path(next_path))}">
<input type="text" name="username" value="cellteach" autocomplete="username" hidden>
<label for="code">Access code</label><br>
<input id="code" name="code" type="password" autocomplete="current-password" required
 autofocus spellcheck="false" style="width:100%;font-size:1.1em;margin:.3em 0">
<button type="submit" style="font-size:1.1em">Open the page</button>
</form></body></html>"""
