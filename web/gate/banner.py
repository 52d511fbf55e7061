"""A line on the page itself, added by the front to viser's index.html: "view only" for a
viewer, "not encrypted" for a plain-HTTP page on the network. It never takes clicks.

A viewer's page also gets a style that makes every control look inactive (greyed, a
not-allowed cursor): what a viewer sends is dropped at the front anyway (`messages.py`), and
a button that looks pressable but does nothing reads as broken. Folders still open and
close, and the 3-D view still turns: those change nothing but the viewer's own screen."""

from __future__ import annotations

import html

from web.gate.tokens import Role

BANNER_ID = "cellteach-gate-banner"
VIEW_ONLY = "View only: this page shows the cell live; nothing on it changes or moves " \
    "anything."
UNENCRYPTED = "Not encrypted: anyone on this network can read this page and its access code. " \
    "Restart cellteach with --certfile and --keyfile to serve HTTPS."


def banner_lines(*, role: Role, unencrypted: bool) -> list[str]:
    lines = []
    if unencrypted:
        lines.append(UNENCRYPTED)
    if role == Role.VIEWER:
        lines.append(VIEW_ONLY)
    return lines


#: Mantine's controls as viser 1.1 renders them (buttons, inputs, sliders, switches, menus).
VIEWER_STYLE = """<style id="cellteach-viewer-style">
.mantine-Button-root, .mantine-ActionIcon-root, .mantine-Input-input, .mantine-Slider-root,
.mantine-Checkbox-root, .mantine-Switch-root, .mantine-SegmentedControl-root,
.mantine-FileButton-root, .mantine-ColorInput-input, .mantine-NumberInput-controls {
  opacity: .45 !important; filter: grayscale(1) !important; cursor: not-allowed !important; }
</style>"""


def with_banner(page: bytes, *, role: Role, unencrypted: bool) -> bytes:
    lines = banner_lines(role=role, unencrypted=unencrypted)
    if role == Role.VIEWER:
        at = page.find(b"</head>")
        style = VIEWER_STYLE.encode()
        page = page + style if at < 0 else page[:at] + style + page[at:]
    if not lines:
        return page
    color = "#b3261e" if unencrypted else "#3b5bdb"
    div = (f'<div id="{BANNER_ID}" role="status" style="position:fixed;left:0;right:0;'
           f'bottom:0;z-index:2147483647;background:{color};color:#fff;'
           'font:13px/1.4 sans-serif;padding:3px 10px;text-align:center;pointer-events:none">'
           + "<br>".join(html.escape(s) for s in lines) + "</div>").encode()
    at = page.rfind(b"</body>")
    return page + div if at < 0 else page[:at] + div + page[at:]
