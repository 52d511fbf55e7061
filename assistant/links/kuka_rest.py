"""Drive a KUKA robot through the REST bridge of source 002 (HTTP, one command at a time).

The bridge knows Cartesian targets only. A planned joint path is executed as synchronous
PTP motions - a PTP between two configurations follows the straight joint-space segment, so
the collision-checked joint path is reproduced - to the FK poses of the path's vertices,
each with the Status/Turn bits of the planned configuration so the controller picks the
planned IK branch (002 left S/T to the user; axis-limit stops were its commonest failure).

Every command is an exact stop (the bridge waits for the robot before answering), so the
path is first *decimated*: vertices a straight joint segment replaces within
`decimation_tol_m` on the arm are dropped (`decimate.py`). Dense planner output of a few
hundred points typically becomes a handful of PTPs.

Improvements over 002, all client-side: a timeout on every request sized to the motion,
LINK_LOST on a dead or silent bridge instead of hanging, errors that quote the raw reply,
and unique upload names (the 002 bridge re-ran the first uploaded file): the module is
renamed to a fresh name and the bridge's answer must name that module.
"""

from __future__ import annotations

import contextlib
import http.client
import itertools
import re
import threading
import time
import urllib.error
import urllib.request
from urllib.parse import urlencode

import numpy as np

from assistant.links import kuka_protocol as kp
from assistant.links.arm_config import arm_config, status_bits, turn_bits
from assistant.links.decimate import exact_stop_targets
from assistant.links.errors import ControllerRefused, ProtocolError
from assistant.links.kuka_protocol import BridgeReply
from assistant.links.link import LinkError, LinkEvent, LinkEventKind, LinkLost, RobotLink
from assistant.links.operator_button import OperatorButton
from assistant.links.timing import time_parametrize, validate_path
from assistant.links.wirelog import NULL, WireLog
from assistant.robots.model import Robot

Array = np.ndarray
_upload_seq = itertools.count(1)


class KukaRestLink(OperatorButton, RobotLink):
    """HTTP client for the 002 KUKA bridge.

    Args:
        robot: model of the arm behind the bridge (kinematics, limits, speeds).
        host, port, base_path: where the bridge listens (``http://host:port/krl``).
        timeout_s: extra seconds allowed beyond a command's expected motion time.
        decimation_tol_m: how far (on the arm) the executed path may leave the planned one.
        set_tcp_on_connect: send the model's TCP with ``/krl/tcp`` so positions agree.
    """

    def __init__(
        self,
        robot: Robot,
        *,
        host: str = "127.0.0.1",
        port: int = 8000,
        base_path: str = "/krl",
        timeout_s: float = 2.0,
        decimation_tol_m: float = 0.002,
        set_tcp_on_connect: bool = True,
        wire: WireLog = NULL,
    ):
        super().__init__()
        self.wire = wire
        if timeout_s <= 0 or decimation_tol_m <= 0:
            raise ValueError("timeout_s and decimation_tol_m must be positive")
        self.robot = robot
        self.base_url = f"http://{host}:{int(port)}/{base_path.strip('/')}"
        self.timeout_s = float(timeout_s)
        self.decimation_tol_m = float(decimation_tol_m)
        self.set_tcp_on_connect = set_tcp_on_connect
        self._radii = robot.arm_radii()
        self._lock = threading.Lock()  # one command at a time, as the bridge requires
        self._stop = threading.Event()
        self._moving = threading.Lock()
        self._connected = False
        self._last_q = np.zeros(robot.dof)
        self.stop_supported: bool | None = None
        #: Commands sent by the last move_path (for reports: how well decimation did).
        self.last_command_count = 0

    # ------------------------------------------------------------------ HTTP
    def _url(self, endpoint: str, params: dict[str, str] | None) -> str:
        return f"{self.base_url}/{endpoint}" + (f"?{urlencode(params)}" if params else "")

    def post(self, endpoint: str, params: dict[str, str] | None = None, *,
             body: bytes = b"", content_type: str = "application/octet-stream",
             timeout_s: float | None = None) -> BridgeReply:
        """One command; returns the parsed reply (any statuscode). Dead bridge -> LinkLost."""
        timeout = self.timeout_s if timeout_s is None else timeout_s
        req = urllib.request.Request(self._url(endpoint, params), data=body, method="POST",
                                     headers={"Content-Type": content_type,
                                              "Connection": "close"})
        self.wire.sent("http", f"POST {req.full_url}" + (f" ({len(body)} bytes)" if body else ""))
        with self._lock:
            try:
                with urllib.request.urlopen(req, timeout=timeout) as resp:
                    raw = resp.read()
                    self.wire.received("http", raw[:500])
            except urllib.error.HTTPError as exc:
                text = exc.read().decode("utf-8", errors="replace")[:200]
                self.wire.received("http", f"HTTP {exc.code} {text}")
                raise LinkError(f"bridge answered /{endpoint} with HTTP {exc.code}: "
                                f"{text!r}") from None
            except TimeoutError:
                raise self._lost(f"no answer to /{endpoint} within {timeout:.2f} s") from None
            except urllib.error.URLError as exc:
                raise self._lost(f"/{endpoint}: {exc.reason}") from None
            except (http.client.HTTPException, ConnectionError, OSError) as exc:
                raise self._lost(f"/{endpoint}: {type(exc).__name__}: {exc}") from None
        return kp.parse_reply(raw, endpoint)

    def command(self, endpoint: str, params: dict[str, str] | None = None, **kw) -> BridgeReply:
        """Like `post`, but any statuscode other than 1 raises `ControllerRefused`."""
        reply = self.post(endpoint, params, **kw)
        if not reply.ok:
            raise ControllerRefused(f"bridge refused /{endpoint}: {reply.describe()}",
                                    code=str(reply.statuscode), raw=reply.raw)
        return reply

    def _lost(self, why: str) -> LinkLost:
        self._connected = False
        return LinkLost(f"KUKA bridge at {self.base_url} lost: {why}")

    # ------------------------------------------------------------------ kinematics
    def _joints_of(self, position: tuple[float, ...], seed: Array,
                   axes: tuple[float, ...] = ()) -> Array:
        """Joints for a reported position: the axes the bridge reports (cellteach's does),
        else the IK solution nearest the last known joints."""
        if len(axes) >= self.robot.dof:
            return np.radians(np.asarray(axes[:self.robot.dof], dtype=float))
        res = self.robot.ik(kp.position_to_T(position), seed)
        if not res.ok:
            res = self.robot.ik(kp.position_to_T(position), seed, position_only=True)
        if not res.ok:
            raise ProtocolError(f"bridge reports a position our model cannot reach: "
                                f"{list(position)}", raw=str(list(position)))
        return res.best(seed)

    def _reply_joints(self, reply: BridgeReply, seed: Array) -> Array:
        return self._joints_of(reply.position, seed, reply.axes)

    def target_params(self, q: Array, speed_scale: float = 1.0) -> dict[str, str]:
        params = kp.pose_params(self.robot.fk(q), status_bits(arm_config(self.robot, q)),
                                turn_bits(q))
        if speed_scale < 1.0:
            params["vel"] = f"{speed_scale * 100.0:.1f}"
        return params

    # ------------------------------------------------------------------ RobotLink
    def connect(self) -> None:
        self._connected = False
        if self.set_tcp_on_connect:
            tcp = self.command("tcp", kp.pose_params(self.robot.T_flange_tool))
            if not np.allclose(kp.position_to_T(tcp.position), self.robot.T_flange_tool,
                               atol=1e-6):
                raise LinkError(f"bridge did not take our TCP: it reports {tcp.position}")
        self._last_q = self._reply_joints(self.command("getpos"), self._last_q)
        self._connected = True

    def close(self) -> None:
        self._connected = False

    @property
    def connected(self) -> bool:
        return self._connected

    def current_joints(self) -> Array:
        if self._connected:
            self._last_q = self._reply_joints(self.command("getpos"), self._last_q)
        return self._last_q.copy()

    def current_pose(self) -> Array:
        return kp.position_to_T(self.command("getpos").position)

    def stop(self) -> None:
        """Ask the bridge to abort the running command (``/krl/stop``, on its own connection)."""
        self._stop.set()
        if self.stop_supported is False:
            return
        req = urllib.request.Request(self._url("stop", None), data=b"", method="POST",
                                     headers={"Connection": "close"})
        try:
            with urllib.request.urlopen(req, timeout=self.timeout_s) as resp:
                resp.read()
            self.stop_supported = True
        except urllib.error.HTTPError as exc:
            if exc.code == 404:
                self.stop_supported = False  # 002 bridge: the current PTP runs to its end
        except (OSError, http.client.HTTPException):
            pass

    # ------------------------------------------------------------------ motions
    def plan_commands(self, joint_path: Array) -> tuple[Array, Array]:
        """The PTP targets (K, dof) for a path and the path index of each (decimated)."""
        path = validate_path(self.robot, joint_path)
        return exact_stop_targets(path, self._last_q, self._radii, self.decimation_tol_m)

    def move_path(self, joint_path: Array, *, speed_scale: float = 1.0) -> LinkEvent:
        path = validate_path(self.robot, joint_path)
        time_parametrize(path[:1], self.robot.limits.velocity, speed_scale)  # checks the scale
        if not self._connected:
            raise LinkError("KUKA bridge link is not connected; call connect() first")
        self._stop.clear()
        self._pressed = None
        if not self._moving.acquire(blocking=False):
            raise LinkError("the robot is already moving")
        try:
            targets, index = self.plan_commands(path)
            self.last_command_count = len(targets)
            return self._run(targets, index, len(path), speed_scale)
        finally:
            self._moving.release()

    def _run(self, targets: Array, index: Array, n_path: int, speed_scale: float) -> LinkEvent:
        v = self.robot.limits.velocity
        for k, q in enumerate(targets):
            if self._stop.is_set():
                kind, text, details = self._stopped_as()
                return self._event(kind, text, int(index[k]), details)
            span = time_parametrize(np.vstack([self._last_q[None], q[None]]), v, speed_scale)
            try:
                reply = self.post("ptp", self.target_params(q, speed_scale),
                                  timeout_s=span.duration * 1.5 + self.timeout_s)
            except LinkLost as exc:
                return self._event(LinkEventKind.LINK_LOST, str(exc), int(index[k]))
            except ProtocolError as exc:
                self._refresh_after_error()
                return self._event(LinkEventKind.ERROR, str(exc), int(index[k]),
                                   {"raw": exc.raw})
            if not reply.ok:
                return self._on_status(reply, int(index[k]))
            self._last_q = q.copy()
            self._emit(LinkEvent(LinkEventKind.MOVED, q.copy(), time.monotonic(),
                                 f"PTP {k + 1}/{len(targets)}", int(index[k])))
        return self._event(LinkEventKind.REACHED, "reached", n_path - 1)

    def _refresh_after_error(self) -> None:
        with contextlib.suppress(LinkError):
            self._last_q = self._reply_joints(self.command("getpos"), self._last_q)

    def _on_status(self, reply: BridgeReply, path_index: int) -> LinkEvent:
        if reply.position and len(reply.position) == 6:
            with contextlib.suppress(ProtocolError):
                self._last_q = self._reply_joints(reply, self._last_q)
        details = {"statuscode": reply.statuscode, "raw": reply.raw,
                   "bridge_message": reply.message}
        if reply.statuscode == kp.STATUS_COLLISION:
            details["source"] = "controller"
            return self._event(LinkEventKind.COLLISION_INDICATED,
                               f"collision indicated by the bridge: {reply.describe()}",
                               path_index, details)
        if reply.statuscode == kp.STATUS_STOPPED:
            kind, text, details = self._stopped_as(details)
            return self._event(kind, text, path_index, details)
        return self._event(LinkEventKind.ERROR, f"bridge refused the motion: {reply.describe()}",
                           path_index, details)

    def _event(self, kind: LinkEventKind, message: str, path_index: int,
               details: dict | None = None) -> LinkEvent:
        ev = LinkEvent(kind, self._last_q.copy(), time.monotonic(), message, path_index,
                       details or {})
        self._emit(ev)
        return ev

    def move_linear(self, T_base_tool: Array, *, speed_scale: float = 1.0) -> LinkEvent:
        """Straight TCP line (``/krl/linmov``) to a pose our model can reach."""
        res = self.robot.ik(np.asarray(T_base_tool, dtype=float), self._last_q)
        if not res.ok:
            raise LinkError(f"LIN target refused before sending: {res.message}")
        q = res.best(self._last_q)
        params = kp.pose_params(T_base_tool)
        if speed_scale < 1.0:
            params["vel"] = f"{speed_scale * 100.0:.1f}"
        return self._single("linmov", params, q)

    def move_circ(self, T_aux: Array, T_target: Array) -> LinkEvent:
        """Circular TCP motion through an auxiliary pose (``/krl/circ``)."""
        for name, T in (("auxiliary", T_aux), ("target", T_target)):
            if not self.robot.ik(np.asarray(T, dtype=float), self._last_q).ok:
                raise LinkError(f"CIRC {name} pose refused before sending: unreachable")
        params = {**kp.pose_params(T_target), **kp.pose_params(T_aux, prefix="aux_")}
        return self._single("circ", params, None)

    def move_home(self) -> LinkEvent:
        """The bridge's base (canon) position."""
        return self._single("base", None, None)

    def _single(self, endpoint: str, params: dict[str, str] | None, q: Array | None,
                ) -> LinkEvent:
        if not self._connected:
            raise LinkError("KUKA bridge link is not connected; call connect() first")
        with self._moving:
            self._stop.clear()
            self._pressed = None
            long = self.timeout_s + 60.0  # Cartesian moves: no cheap duration estimate
            try:
                reply = self.post(endpoint, params, timeout_s=long)
            except LinkLost as exc:
                return self._event(LinkEventKind.LINK_LOST, str(exc), 0)
            except ProtocolError as exc:
                return self._event(LinkEventKind.ERROR, str(exc), 0, {"raw": exc.raw})
            if not reply.ok:
                return self._on_status(reply, 0)
            self._last_q = self._joints_of(reply.position, self._last_q if q is None else q,
                                           reply.axes)
            return self._event(LinkEventKind.REACHED, "reached", 0)

    # ------------------------------------------------------------------ programs
    def upload_program(self, name: str, files: dict[str, bytes]) -> str:
        """Upload a KRL module (.src and optional .dat) under a fresh name; it runs at once.

        The module is renamed (KRL needs DEF name = file name) to ``<name>_<time><n>``; the
        bridge must answer with that name, otherwise it ran something else (the 002 bug).
        """
        if not self._connected:
            raise LinkError("KUKA bridge link is not connected; call connect() first")
        srcs = [f for f in files if f.lower().endswith(".src")]
        if len(srcs) != 1:
            raise LinkError(f"need exactly one .src file, got {sorted(files)}")
        src_text = files[srcs[0]].decode("utf-8")
        old = kp.krl_module_name(src_text)
        if old is None:
            raise LinkError(f"{srcs[0]} has no DEF line")
        base = re.sub(r"[^A-Za-z0-9_]", "_", name).strip("_")[:10] or "prog"
        if not base[0].isalpha():
            base = "p" + base[:9]
        unique = f"{base}_{int(time.time() * 100) % 36**6:x}{next(_upload_seq)}"[:24]
        out: list[tuple[str, bytes]] = []
        for fname, data in sorted(files.items(), key=lambda kv: kv[0].lower().endswith(".src")):
            ext = fname.rsplit(".", 1)[-1].lower()
            if ext not in ("src", "dat"):
                raise LinkError(f"{fname}: only .src and .dat files can be uploaded")
            text = data.decode("utf-8")
            try:
                text = kp.rename_krl_module(text, old, unique)
            except ValueError as exc:
                raise LinkError(f"{fname}: {exc}") from None
            out.append((f"{unique}.{ext}", text.encode("utf-8")))
        for fname, data in out:
            body, ctype = kp.multipart("file", fname, data)
            reply = self.command("uploadfile", body=body, content_type=ctype,
                                 timeout_s=self.timeout_s + 600.0)
            if reply.program and reply.program.upper() != unique.upper():
                raise LinkError(f"bridge stored/ran {reply.program!r} instead of {unique!r}: "
                                "it re-runs an earlier upload (the known 002 bridge flaw)")
            if not reply.program:
                raise LinkError(f"bridge did not confirm which module it ran; raw {reply.raw!r}")
            if fname.endswith(".src"):
                self._last_q = self._reply_joints(reply, self._last_q)
        return unique
