"""The viser page: one panel per workflow state, the 3-D scene, downloads. No domain logic.

`web` is a view and controller over one `assistant.session.Session` shared by every browser:
it renders the session's queries, redraws on the session's events and calls the session's
methods. Units are converted (mm/deg <-> m/rad) at this edge only. It imports `viser`;
nothing under `assistant`, `workflow` or `vision` may import `web`.

    from web import serve
    app = serve(session, host="127.0.0.1", port=8080)
"""

from web.app import App, build_app, serve

__all__ = ["App", "build_app", "serve"]
