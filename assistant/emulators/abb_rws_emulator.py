"""An ABB IRC5 speaking Robot Web Services 1.0 on localhost, with a model arm behind it.

Enough of RWS that abb-robot-client's `RWS` class and our `AbbRwsLink` work against it
unmodified: digest login and session cookies, mastership (one holder; RAPID writes by anyone
else get 403), joint target / robtarget, controller state, operating mode, execution state,
tasks, modules, symbol values, the event log, the file service (PUT/GET/DELETE), loadmod /
unloadmod, resetpp, start / stop. Unknown resources answer 404, unknown actions or
parameters 400, a wrong method 405, each with an RWS error body; answers are JSON only
(``?json=1``; the XHTML flavour is refused with 400).

The arm is whatever `Robot` it is given (tests use the UR5 of example-robot-data as a
stand-in 6-axis arm; the jointtarget carries rax_1..rax_6). It moves in (scaled) time at the
model's speeds, stops before hidden obstacles (event 50204), and produces faults on request
(`faults.Faults`): a drop halts the arm and cuts every connection for `unplug_s`.

Run as a script for demos::

    python -m assistant.emulators.abb_rws_emulator --port 8080
"""

from __future__ import annotations

import argparse
import contextlib
import socket
import ssl
import threading
import time
from collections.abc import Iterable
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path
from urllib.parse import parse_qs, unquote, urlsplit

import numpy as np

from assistant.collision.reports import ObstacleView
from assistant.emulators.abb_controller import RapidController, RwsError, confdata
from assistant.emulators.abb_rws_auth import DigestSessions, Session
from assistant.emulators.abb_rws_events import SubscriptionHub, elog_event, exec_event
from assistant.emulators.arm import EmulatedArm
from assistant.emulators.faults import Faults, Received
from assistant.emulators.until_stopped import install_stop_handlers, wait_until_stopped
from assistant.links import abb_rws_protocol as rp
from assistant.links.abb_rws_dialect import Rws, v2_to_v1
from assistant.robots.framed import controller_view
from assistant.robots.model import Robot

Array = np.ndarray
#: The OmniCore emulator's self-signed certificate and key (test only; a controller ships its
#: own self-signed one too).
CERTFILE = Path(__file__).with_name("omnicore_selfsigned.pem")
TASK = "T_ROB1"
MECHUNIT = "ROB_1"
CYCLES = ("asis", "once", "forever", "oncedone")


class AbbRwsEmulator:
    """HTTP server speaking RWS 1.0 (JSON), driving a model arm.

    Args:
        robot: the arm behind the controller (its limits are the controller's).
        users: login name -> password (default: the IRC5's ``Default User``/``robotics``).
        hidden_obstacles: obstacles only the emulator knows; the arm stops before them.
        time_scale: robot seconds per wall second.
        unplug_s: after a drop fault, wall seconds during which every request is cut.
    """

    def __init__(
        self,
        robot: Robot,
        *,
        users: dict[str, str] | None = None,
        hidden_obstacles: Iterable[ObstacleView] = (),
        host: str = "127.0.0.1",
        port: int = 0,
        time_scale: float = 1.0,
        tick_s: float = 0.008,
        start_q: Array | None = None,
        faults: Faults | None = None,
        unplug_s: float = 0.3,
        rws_version: int = 1,
        certfile: str | Path | None = None,
    ):
        self.robot = robot
        self.host = host
        self.rws = Rws(rws_version)
        self.certfile = Path(certfile) if certfile else CERTFILE
        self.faults = faults or Faults()
        self.sessions = DigestSessions(users or {"Default User": "robotics"},
                                       basic=rws_version == 2)
        self.events = SubscriptionHub(self.rws.subprotocol)
        self.arm = EmulatedArm(robot, hidden_obstacles=hidden_obstacles, time_scale=time_scale,
                               tick_s=tick_s, start_q=start_q, faults=self.faults,
                               on_drop=self._on_drop)
        #: The arm as the controller counts poses: from the robot's program frame.
        self.view = controller_view(robot)
        self.rapid = RapidController(self.view, self.arm, time_scale)
        self.rapid.on_exec_change = lambda st: self.events.publish(
            "/rw/rapid/execution;ctrlexecstate", exec_event(st))
        self.rapid.on_log = lambda n: self.events.publish("/rw/elog/0", elog_event(n))
        self.unplug_s = float(unplug_s)
        self._unplugged_until = 0.0
        self.received: list[Received] = []
        self._recv_lock = threading.Lock()
        self._port_req = port
        self._server: ThreadingHTTPServer | None = None
        self._thread: threading.Thread | None = None

    # ------------------------------------------------------------------ lifecycle
    def start(self) -> AbbRwsEmulator:
        emu = self

        class Handler(BaseHTTPRequestHandler):
            protocol_version = "HTTP/1.1"
            timeout = 2.0  # an idle keep-alive client must not hold a thread forever

            def log_message(self, *args: object) -> None:  # keep test output clean
                return

            def do_GET(self) -> None:  # noqa: N802 (http.server naming)
                emu._handle(self, "GET")

            def do_POST(self) -> None:  # noqa: N802
                emu._handle(self, "POST")

            def do_PUT(self) -> None:  # noqa: N802
                emu._handle(self, "PUT")

            def do_DELETE(self) -> None:  # noqa: N802
                emu._handle(self, "DELETE")

        class Server(ThreadingHTTPServer):
            daemon_threads = True
            allow_reuse_address = True

        self._server = Server((self.host, self._port_req), Handler)
        if self.rws.version == 2:  # OmniCore: HTTPS with the controller's own certificate
            ctx = ssl.SSLContext(ssl.PROTOCOL_TLS_SERVER)
            ctx.load_cert_chain(self.certfile)
            self._server.socket = ctx.wrap_socket(self._server.socket, server_side=True,
                                                  do_handshake_on_connect=False)
        self._thread = threading.Thread(target=self._server.serve_forever,
                                        kwargs={"poll_interval": 0.05}, name="abb-rws",
                                        daemon=True)
        self._thread.start()
        self.arm.start()
        return self

    def close(self) -> None:
        self.events.closing.set()
        self.rapid.stop()
        self.arm.close()
        if self._server is not None:
            self._server.shutdown()
            self._server.server_close()
        if self._thread is not None:
            self._thread.join(timeout=2.0)

    def __enter__(self) -> AbbRwsEmulator:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.close()

    @property
    def port(self) -> int:
        assert self._server is not None, "start() first"
        return self._server.server_address[1]

    @property
    def base_url(self) -> str:
        return f"{self.rws.scheme}://{self.host}:{self.port}"

    def received_paths(self) -> list[str]:
        with self._recv_lock:
            return [r.channel for r in self.received]

    def _on_drop(self) -> None:
        self._unplugged_until = time.monotonic() + self.unplug_s
        self.sessions.forget_all()

    # ------------------------------------------------------------------ HTTP
    def _handle(self, h: BaseHTTPRequestHandler, method: str) -> None:
        length = int(h.headers.get("Content-Length") or 0)
        body = h.rfile.read(length) if length else b""
        if time.monotonic() < self._unplugged_until:
            self._cut(h)
            return
        url = urlsplit(h.path)
        with self._recv_lock:
            self.received.append(Received(f"{method} {url.path}", time.monotonic(), url.query))
        session, new = self.sessions.authenticate(method, h.path, h.headers)
        if session is None:
            self._send(h, 401, "<html><body>401 Unauthorized</body></html>", "text/html",
                       extra=[("WWW-Authenticate", self.sessions.challenge())])
            return
        cookies = [("Set-Cookie", c) for c in self.sessions.cookies(session)] if new else []
        query = {k: v[-1] for k, v in parse_qs(url.query).items()}
        form = {k: v[-1] for k, v in parse_qs(body.decode("utf-8", errors="replace")).items()} \
            if method == "POST" else {}
        path = unquote(url.path)
        v = self.rws.version
        base = f"{self.base_url}{path.rsplit('/', 1)[0]}/"
        if path.startswith("/poll/") and method == "GET":
            self.events.serve(h, int(path.rsplit("/", 1)[-1] or 0))
            return
        try:
            if path == "/subscription" and method == "POST":
                self._subscription(h, body, cookies)
                return
            if v == 2:
                path, query = self._v2(h, method, path, query)
            status, out, ctype = self._route(method, path, query, form, body, session)
        except RwsError as exc:
            status, out, ctype = exc.http, rp.error_body(base, exc.code, exc.msg, v), \
                "application/json"
        except (ValueError, KeyError) as exc:
            status, out, ctype = 400, rp.error_body(base, rp.RC_BAD_REQUEST, str(exc), v), \
                "application/json"
        if isinstance(out, list):
            out = rp.envelope(base, out, v)
        if v == 2 and ctype == "application/json":
            ctype = "application/hal+json;v=2.0"
        self._send(h, status, out, ctype, extra=cookies)

    def _v2(self, h: BaseHTTPRequestHandler, method: str, path: str, query: dict[str, str],
            ) -> tuple[str, dict[str, str]]:
        """An RWS 2.0 request as the 1.0 resource and action it means (`v2_to_v1`)."""
        if not path.startswith("/rw/"):
            return path, query
        if "action" in query:
            raise RwsError(405, rp.RC_BAD_REQUEST, f"{method} {path}?action=... is RWS 1.0; "
                           "RWS 2.0 puts the action in the path")
        if "application/hal+json" not in h.headers.get("Accept", ""):
            raise RwsError(406, rp.RC_BAD_REQUEST, "Server cannot generate response for given "
                           "accept header (application/hal+json;v=2.0)")
        res, action = v2_to_v1(path)
        query = {**query, "json": "1"}
        if action is not None:
            query["action"] = action
        elif res == "/rw/panel/ctrlstate" and method == "POST":
            query["action"] = "setctrlstate"
        return res, query

    def _subscription(self, h: BaseHTTPRequestHandler, body: bytes,
                      cookies: list[tuple[str, str]]) -> None:
        n = self.events.create(body.decode("utf-8", errors="replace"))
        scheme = "wss" if self.rws.version == 2 else "ws"
        url = f"{scheme}://{self.host}:{self.port}/poll/{n}"
        page = (f'<?xml version="1.0" encoding="utf-8"?><html xmlns="http://www.w3.org/1999/'
                f'xhtml"><body><div class="state"><a href="{url}" rel="self">'
                f'</a></div></body></html>')
        self._send(h, 201, page, "application/xhtml+xml",
                   extra=cookies + [("Location", url)])

    def _cut(self, h: BaseHTTPRequestHandler) -> None:
        """The cable is out: the connection dies without an answer."""
        with contextlib.suppress(OSError):
            h.connection.shutdown(socket.SHUT_RDWR)
        h.close_connection = True

    def _send(self, h: BaseHTTPRequestHandler, status: int, out: str | bytes, ctype: str,
              extra: list[tuple[str, str]] = ()) -> None:
        """Answer (after the armed delay; a JSON text may be replaced by the armed garbage)."""
        if isinstance(out, str) and out:
            out, delay = self.faults.take_reply(out)
        else:
            delay = self.faults.reply_delay_s
        data = out.encode("utf-8", errors="replace") if isinstance(out, str) else out
        if status == 204:
            data = b""
        if delay > 0:
            time.sleep(delay)
        try:
            h.send_response(status)
            for k, v in extra:
                h.send_header(k, v)
            if status != 204:
                h.send_header("Content-Type", ctype)
            h.send_header("Content-Length", str(len(data)))
            h.end_headers()
            h.wfile.write(data)
        except OSError:
            h.close_connection = True

    # ------------------------------------------------------------------ resources
    def _route(self, method: str, path: str, q: dict[str, str], form: dict[str, str],
               body: bytes, s: Session) -> tuple[int, str | bytes | list, str]:
        js = "application/json"
        if path.startswith("/fileservice/") or path == "/fileservice":
            return self._files(method, path[len("/fileservice"):].strip("/"), q, body)
        if path == "/logout":
            self.sessions.logout(s)
            return 204, "", js
        if q.get("json") != "1":
            raise RwsError(400, rp.RC_BAD_REQUEST, "this controller answers JSON only: ?json=1")
        action = q.get("action")
        parts = [p for p in path.strip("/").split("/") if p]
        if parts[:1] != ["rw"]:
            raise RwsError(404, rp.RC_NOT_FOUND, f"no resource {path}")
        res = "/".join(parts[1:])
        if method == "GET" and action is None:
            return 200, self._get(res, parts, q), js
        if method != "POST" or action is None:
            raise RwsError(405 if method != "POST" else 400, rp.RC_BAD_REQUEST,
                           f"{method} {path} needs ?action=... (POST) or is read-only")
        self._post(res, action, form, s)
        return 204, "", js

    def _get(self, res: str, parts: list[str], q: dict[str, str]) -> list[dict]:
        c = self.rapid
        if res == "system":
            return [{"_type": "sys-system", "_title": "system", "name": "cellteach-IRC5",
                     "rwversion": "6.15.00.00", "rwversionname": "6.15.00"}]
        if res == "panel/ctrlstate":
            return [{"_type": "pnl-ctrlstate", "_title": "ctrlstate",
                     "ctrlstate": "motoron" if c.motors_on else "motoroff"}]
        if res == "panel/opmode":
            return [{"_type": "pnl-opmode", "_title": "opmode", "opmode": "AUTO"}]
        if res == "panel/speedratio":
            return [{"_type": "pnl-speedratio", "_title": "speedratio", "speedratio": "100"}]
        if res == "rapid/execution":
            return [{"_type": "rap-execution", "_title": "execution",
                     "ctrlexecstate": "running" if c.running else "stopped", "cycle": c.cycle}]
        if res in ("rapid/tasks", f"rapid/tasks/{TASK}"):
            return [{"_type": "rap-task-li", "_title": TASK, "name": TASK, "type": "norm",
                     "taskstate": "link", "excstate": "started" if c.running else "ready",
                     "active": "On", "motiontask": "TRUE"}]
        if res in ("rapid/modules", f"rapid/tasks/{TASK}/modules"):
            if q.get("task", TASK) != TASK:
                raise RwsError(400, rp.RC_BAD_REQUEST, f"no task {q.get('task')}")
            with c.lock:
                return [{"_type": "rap-module-info-li", "_title": m.name, "name": m.name,
                         "type": "ProgMod"} for m, _ in c.modules.values()]
        if res.startswith(f"rapid/symbol/data/RAPID/{TASK}/"):
            names = parts[6:]
            if len(names) not in (1, 2):
                raise RwsError(404, rp.RC_NOT_FOUND, f"no symbol {res}")
            value = c.symbol(names[0] if len(names) == 2 else None, names[-1])
            return [{"_type": "rap-data", "_title": "/".join(["RAPID", TASK] + names),
                     "value": value}]
        if res == f"motionsystem/mechunits/{MECHUNIT}/jointtarget":
            return [rp.jointtarget_state(self.arm.q, MECHUNIT)]
        if res == f"motionsystem/mechunits/{MECHUNIT}/robtarget":
            return [self._robtarget(q)]
        if res.rstrip("/") == "elog/0":
            with c.lock:
                return [e.state() for e in reversed(c.elog)]
        raise RwsError(404, rp.RC_NOT_FOUND, f"no resource /rw/{res}")

    def _robtarget(self, q: dict[str, str]) -> dict:
        coord = q.get("coordinate", "Base")
        if coord not in ("Base", "World", "Wobj"):
            raise RwsError(400, rp.RC_BAD_REQUEST, f"coordinate {coord} not supported")
        joints = self.arm.q
        flange = self.view.fk(joints) @ np.linalg.inv(self.view.T_flange_tool)
        T = flange @ self.rapid.frame(q.get("tool", "tool0"), "tooldata")
        if coord == "Wobj":
            T = np.linalg.inv(self.rapid.frame(q.get("wobj", "wobj0"), "wobjdata")) @ T
        return rp.robtarget_state(T, confdata(self.view, joints))

    def _post(self, res: str, action: str, form: dict[str, str], s: Session) -> None:
        c, ses = self.rapid, self.sessions
        if res in ("mastership", "mastership/rapid", "mastership/motion", "mastership/cfg"):
            if action == "request":
                if not ses.request_mastership(s):
                    raise RwsError(403, rp.RC_HELD_BY_OTHER, "mastership is held by another "
                                   "client")
                return
            if action == "release":
                if not ses.release_mastership(s):
                    raise RwsError(403, rp.RC_HELD_BY_OTHER, "mastership is held by another "
                                   "client")
                return
        elif res == "rapid/execution":
            if action == "stop":  # a stop always gets through, whoever holds mastership
                c.stop()
                return
            if action in ("start", "resetpp"):
                self._writable(s, need_master=False)
                if action == "resetpp":
                    c.resetpp()
                    return
                cycle = form.get("cycle", "asis")
                if cycle not in CYCLES:
                    raise RwsError(400, rp.RC_BAD_REQUEST, f"cycle {cycle!r} is not one of "
                                   f"{CYCLES}")
                c.start(cycle)
                return
        elif res == f"rapid/tasks/{TASK}":
            if action == "loadmod":
                self._writable(s, need_master=True)
                if "modulepath" not in form:
                    raise RwsError(400, rp.RC_BAD_REQUEST, "loadmod needs modulepath")
                c.load(form["modulepath"], form.get("replace", "false").lower() == "true")
                return
            if action == "unloadmod":
                self._writable(s, need_master=True)
                if "module" not in form:
                    raise RwsError(400, rp.RC_BAD_REQUEST, "unloadmod needs module")
                c.unload(form["module"])
                return
            if action in ("activate", "deactivate"):
                return
        elif res == f"rapid/tasks/{TASK}/pcp" and action == "set-pp-routine":
            self._writable(s, need_master=False)
            if "routine" not in form:
                raise RwsError(400, rp.RC_BAD_REQUEST, "set-pp-routine needs routine")
            module = form.get("module") or self._module_of(form["routine"])
            c.set_pp_routine(module, form["routine"])
            return
        elif res == "panel/ctrlstate" and action == "setctrlstate":
            st = form.get("ctrl-state")
            if st not in ("motoron", "motoroff"):
                raise RwsError(400, rp.RC_BAD_REQUEST, f"ctrl-state {st!r} is not "
                               "motoron/motoroff")
            if st == "motoroff":
                c.stop()
            c.motors_on = st == "motoron"
            return
        else:
            raise RwsError(404, rp.RC_NOT_FOUND, f"no resource /rw/{res}")
        raise RwsError(400, rp.RC_BAD_REQUEST, f"/rw/{res} has no action {action!r}")

    def _module_of(self, routine: str) -> str:
        with self.rapid.lock:
            for name, (mod, _) in self.rapid.modules.items():
                if routine.upper() in mod.procs:
                    return name
        raise RwsError(400, rp.RC_NOT_FOUND, f"no routine {routine} in the task")

    def _writable(self, s: Session, *, need_master: bool) -> None:
        if self.sessions.held_by_other(s):
            raise RwsError(403, rp.RC_HELD_BY_OTHER, "mastership is held by another client")
        if need_master and not self.sessions.holds(s):
            raise RwsError(403, rp.RC_NOT_MASTER, "request mastership first")

    def _files(self, method: str, path: str, q: dict[str, str], body: bytes,
               ) -> tuple[int, str | bytes | list, str]:
        c = self.rapid
        if not path:
            raise RwsError(404, rp.RC_NOT_FOUND, "no file given")
        if method == "PUT":
            return (201 if c.put_file(path, body) else 200), "", "text/plain"
        key = c.key(path)
        with c.lock:
            if method == "DELETE":
                if c.files.pop(key, None) is None:
                    raise RwsError(404, rp.RC_NOT_FOUND, f"no file {path}")
                return 204, "", "text/plain"
            if method != "GET":
                raise RwsError(405, rp.RC_BAD_REQUEST, f"{method} on a file")
            if key in c.files:
                return 200, c.files[key], "application/octet-stream"
            inside = [k for k in c.files if k.startswith(key + "/")]
            if not inside:
                raise RwsError(404, rp.RC_NOT_FOUND, f"no file or directory {path}")
            names = sorted({c.names[k][len(key) + 1:].split("/")[0] for k in inside})
        return 200, [{"_type": "fs-file", "_title": n} for n in names], "application/json"


def main(argv: list[str] | None = None) -> None:
    from assistant.emulators.melfa_emulator import _parse_box
    from assistant.robots.catalog import installed_robot_urdf
    from assistant.robots.urdf_robot import URDFRobot

    ap = argparse.ArgumentParser(description="ABB IRC5 RWS 1.0 emulator (UR5 model arm)")
    ap.add_argument("--host", default="127.0.0.1")
    ap.add_argument("--port", type=int, default=8080)
    ap.add_argument("--time-scale", type=float, default=1.0)
    ap.add_argument("--hidden-box", type=_parse_box, action="append", default=[],
                    help="hidden obstacle box x,y,z,sx,sy,sz in mm (repeatable)")
    args = ap.parse_args(argv)
    path, share = installed_robot_urdf(
        "example-robot-data/robots/ur_description/urdf/ur5_robot.urdf")
    robot = URDFRobot.from_file(path, package_dirs=[share], tool_link="tool0")
    emu = AbbRwsEmulator(robot, hidden_obstacles=args.hidden_box, host=args.host,
                         port=args.port, time_scale=args.time_scale)
    with emu:
        install_stop_handlers()
        print(f"ABB RWS emulator on {emu.base_url} (Default User / robotics); Ctrl-C to stop",
              flush=True)
        wait_until_stopped()


if __name__ == "__main__":
    main()
