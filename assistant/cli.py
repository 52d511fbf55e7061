"""The `cellteach` command line: serve the UI (default), run scripted sessions, list cells."""

from __future__ import annotations

import argparse
import sys


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="cellteach", description=__doc__)
    sub = p.add_subparsers(dest="command")
    serve = sub.add_parser("serve", help="start the web UI (the default command)")
    serve.add_argument("--host", default="127.0.0.1")
    serve.add_argument("--port", type=int, default=8080)
    return p


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    if args.command in (None, "serve"):
        host = getattr(args, "host", "127.0.0.1")
        port = getattr(args, "port", 8080)
        import time

        import viser

        server = viser.ViserServer(host=host, port=port)
        server.gui.add_markdown("# cellteach\nThe assistant UI is being built.")
        print(f"cellteach: serving on http://{host}:{port}", file=sys.stderr)
        while True:
            time.sleep(3600)
    return 0
