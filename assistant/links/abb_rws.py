"""Drive an ABB robot through Robot Web Services: an IRC5 (RobotWare 6, RWS 1.0) or an
OmniCore (RobotWare 7, RWS 2.0: HTTPS, Basic login, v2 content types and paths -
`abb_rws_dialect` lists the differences).

Login is HTTP digest (1.0) or Basic over TLS (2.0; default ``Default User`` /
``robotics``), then the controller's session cookie. RAPID writes (loadmod, unloadmod) take
mastership and release it at once, so the FlexPendant is blocked only while we load;
start / set-PP need only that nobody else holds it, and stop always gets through.

A task as shipped already holds a ``PROC main()`` (the cell's own program), and RAPID allows
one main per task: loading a second module with a main fails. So nothing we load has a
main - the exploration module's routine is ``cellmove``, an exported program's main is
renamed ``ct_<module>`` - and the link starts it with "set PP to routine" (RWS 1.0
``/rw/rapid/tasks/{task}/pcp?action=set-pp-routine``, 2.0 ``.../pcp/routine``; ABB's RWS
manual), then ``start``; the cell's main module is never touched.

Exploration moves: RWS has no "move to" resource, so a planned joint path is decimated (as
for KUKA: dropped vertices keep the arm within `decimation_tol_m`) and uploaded as a short
module ``CellMove`` whose routine is MoveAbsJ through the joint targets with exact stops,
then loaded, started and watched: the end comes as an execution-state event on an RWS
subscription (websocket, `abb_rws_subscription`), the joints are read at `poll_period_s`
(5 Hz by default, as ABB's own ROS driver does) - not 100 requests a second. We chose
short modules over a resident server module whose PERS variables we would set: it needs
nothing pre-installed on the controller, the controller checks every target itself, and a
few hundred milliseconds of loadmod per exploration move are nothing next to the motion.
EGM streaming is out of scope. Where the arm stopped is read back; the path index is that
of the target the arm was heading for. Why it stopped comes from the event log: 50204
(motion supervision, what collision detection raises) -> COLLISION_INDICATED, other
errors -> ERROR quoting the entry.

Every request has a timeout - `timeout_s` for reads, `load_timeout_s` (30 s) for file
uploads and module loads, which take seconds on a real controller; a silent, dead or
garbling controller gives LINK_LOST or an ERROR event (after a best-effort stop), never a
hang. Python's urllib does the HTTP (abb-robot-client's RWS class sets no timeouts and has
no mastership or loadmod calls; the tests use it to check that our emulator speaks the real
protocol).
"""

from __future__ import annotations

import base64
import contextlib
import http.client
import http.cookiejar
import re
import ssl
import threading
import time
import urllib.error
import urllib.request
from urllib.parse import quote, urlencode

import numpy as np

from assistant.links import abb_rws_protocol as rp
from assistant.links.abb_rws_dialect import START_FORM, V2_FORM, V2_JSON, Rws
from assistant.links.abb_rws_subscription import (
    ExecutionSubscription,
    subscription_form,
    websocket_url,
)
from assistant.links.decimate import exact_stop_targets
from assistant.links.errors import ControllerRefused, ProtocolError
from assistant.links.link import LinkError, LinkEvent, LinkEventKind, LinkLost, RobotLink
from assistant.links.operator_button import OperatorButton
from assistant.links.timing import time_parametrize, validate_path
from assistant.links.wirelog import NULL, WireLog
from assistant.robots.model import Robot

Array = np.ndarray
MODULE_EXTENSIONS = (".mod", ".modx", ".sys", ".sysx")
#: A joint change between two reads above this is motion (rad); a standing arm reads the
#: same jointtarget every time.
MOVING_RAD = 1e-5


class AbbRwsLink(OperatorButton, RobotLink):
    """RWS client for the motion task of an IRC5 (`rws_version` 1) or an OmniCore (2).

    Args:
        robot: model of the arm (kinematics, limits, speeds); at most 6 axes.
        host, port: the controller's WAN port (80 on an IRC5, 443 on an OmniCore; None:
            that default) or RobotStudio's virtual controller.
        username, password: an RWS user (the default is ``Default User``/``robotics``).
        task, mechunit, home_dir: RAPID task, mechanical unit, where modules are uploaded.
        timeout_s: longest wait for a reply to a read; moves wait their expected time more.
        load_timeout_s: longest wait for a file upload, module load or unload.
        poll_period_s: how often the joints of a running program are read.
        joint_tcp_speed_mm_s: RAPID speed written for a MoveAbsJ at full joint speed.
        verify_tls: check the OmniCore's certificate (it ships self-signed: off by default).
        subscribe: follow the execution state over an RWS subscription (else poll it).
    """

    def __init__(
        self,
        robot: Robot,
        *,
        host: str = "127.0.0.1",
        port: int | None = None,
        username: str = "Default User",
        password: str = "robotics",
        task: str = "T_ROB1",
        mechunit: str = "ROB_1",
        home_dir: str = "$HOME",
        timeout_s: float = 1.0,
        poll_period_s: float = 0.2,
        decimation_tol_m: float = 0.002,
        joint_tcp_speed_mm_s: float = 1000.0,
        rws_version: int = 1,
        load_timeout_s: float = 30.0,
        verify_tls: bool = False,
        subscribe: bool = True,
        wire: WireLog = NULL,
    ):
        super().__init__()
        if robot.dof > 6:
            raise LinkError(f"{robot.name} has {robot.dof} axes; an IRC5 robot has at most 6")
        if min(timeout_s, poll_period_s, decimation_tol_m, joint_tcp_speed_mm_s) <= 0:
            raise ValueError("timeouts, poll period, tolerance and speed must be positive")
        self.robot = robot
        self.rws = Rws(rws_version)
        self.host = host
        self.port = self.rws.default_port if port is None else int(port)
        self.base_url = f"{self.rws.scheme}://{host}:{self.port}"
        self.task, self.mechunit, self.home_dir = task, mechunit, home_dir.rstrip("/")
        self.timeout_s = float(timeout_s)
        self.load_timeout_s = max(float(load_timeout_s), self.timeout_s)
        self.wire = wire
        self.use_subscription = subscribe
        self.subscription: ExecutionSubscription | None = None
        self._tls = ssl.create_default_context()
        if not verify_tls:
            self._tls.check_hostname = False
            self._tls.verify_mode = ssl.CERT_NONE
        self.poll_period_s = float(poll_period_s)
        self.decimation_tol_m = float(decimation_tol_m)
        self.joint_tcp_speed_mm_s = float(joint_tcp_speed_mm_s)
        self._credentials = (username, password)
        self._radii = robot.arm_radii()
        self._lock = threading.Lock()  # one request at a time (digest nonce counts)
        self._stop = threading.Event()
        self._moving = threading.Lock()
        self._connected = False
        self._last_q = np.zeros(robot.dof)
        self._elog_seen = 0
        #: Modules this link loaded (unloaded before the next program is loaded).
        self.loaded: list[str] = []
        #: (module, routine) of the uploaded program `run_program` starts.
        self.program: tuple[str, str] | None = None
        self.last_command_count = 0
        self._opener = self._new_opener()

    def _new_opener(self) -> urllib.request.OpenerDirector:
        self._cookies = http.cookiejar.CookieJar()
        handlers: list = [urllib.request.HTTPCookieProcessor(self._cookies),
                          urllib.request.HTTPSHandler(context=self._tls)]
        if self.rws.version == 1:
            pw = urllib.request.HTTPPasswordMgrWithDefaultRealm()
            pw.add_password(None, self.base_url, *self._credentials)
            handlers.append(urllib.request.HTTPDigestAuthHandler(pw))
        return urllib.request.build_opener(*handlers)

    def _basic(self) -> str:
        return "Basic " + base64.b64encode(":".join(self._credentials).encode()).decode()

    # ------------------------------------------------------------------ HTTP
    def request(self, method: str, resource: str, form: dict[str, str] | None = None, *,
                body: bytes | None = None, json: bool = True,
                timeout_s: float | None = None) -> bytes:
        """One RWS request; the reply body. Refusals raise ControllerRefused, silence LinkLost."""
        timeout = self.timeout_s if timeout_s is None else float(timeout_s)
        url = f"{self.base_url}/{quote(resource.lstrip('/'), safe='/$?=&;')}"
        if json and self.rws.version == 1:
            url += ("&" if "?" in url else "?") + "json=1"
        data = urlencode(form).encode() if form is not None else body
        req = urllib.request.Request(url, data=data, method=method)
        v2 = self.rws.version == 2
        if form is not None:
            req.add_header("Content-Type", V2_FORM if v2 else
                           "application/x-www-form-urlencoded")
        if v2:
            req.add_header("Accept", V2_JSON)
            req.add_header("Authorization", self._basic())
        what = f"{method} /{resource.split('?')[0].lstrip('/')}"
        self.wire.sent("http", f"{method} {url}" + (f" {urlencode(form)}" if form else "")
                       + (f" ({len(body)} bytes)" if body else ""))
        with self._lock:
            try:
                with self._opener.open(req, timeout=timeout) as resp:
                    out = resp.read()
                    self.wire.received("http", f"{resp.status} {out[:300]!r}")
                    return out
            except urllib.error.HTTPError as exc:
                raw = exc.read()
                self.wire.received("http", f"{exc.code} {raw[:300]!r}")
                if exc.code == 401:
                    raise LinkError(f"controller at {self.base_url} refused the login of "
                                    f"{self._credentials[0]!r} (HTTP 401)") from None
                st = rp.error_status(raw)
                text = raw.decode("utf-8", errors="replace")[:200]
                if st is None:
                    raise ControllerRefused(f"controller answered {what} with HTTP {exc.code}:"
                                            f" {text!r}", code=str(exc.code), raw=text) from None
                raise ControllerRefused(f"controller refused {what}: HTTP {exc.code}, code "
                                        f"{st[0]}: {st[1]}", code=str(st[0]), raw=text) from None
            except TimeoutError:
                raise self._lost(f"no answer to {what} within {timeout:.2f} s") from None
            except urllib.error.URLError as exc:
                raise self._lost(f"{what}: {exc.reason}") from None
            except (http.client.HTTPException, ConnectionError, OSError) as exc:
                raise self._lost(f"{what}: {type(exc).__name__}: {exc}") from None

    def _lost(self, why: str) -> LinkLost:
        self._connected = False
        return LinkLost(f"ABB controller at {self.base_url} lost: {why}")

    def get_states(self, resource: str) -> list[dict]:
        return rp.states(self.request("GET", resource), resource.split("?")[0])

    def get_state(self, resource: str, type_: str) -> dict:
        return rp.state(self.request("GET", resource), resource.split("?")[0], type_)

    # ------------------------------------------------------------------ controller state
    def controller_state(self) -> str:
        return str(self.get_state(self.rws.ctrlstate(), "pnl-ctrlstate")["ctrlstate"])

    def operation_mode(self) -> str:
        return str(self.get_state("rw/panel/opmode", "pnl-opmode")["opmode"])

    def execution_state(self) -> str:
        return str(self.get_state("rw/rapid/execution", "rap-execution")["ctrlexecstate"])

    def event_log(self) -> list[rp.ElogEntry]:
        """Entries of event log 0, oldest first."""
        return sorted(rp.parse_elog(self.request("GET", "rw/elog/0/?lang=en")),
                      key=lambda e: e.seqnum)

    def new_errors(self) -> list[rp.ElogEntry]:
        """Error entries since the last look (the baseline moves on)."""
        entries = self.event_log()
        new = [e for e in entries if e.seqnum > self._elog_seen]
        if entries:
            self._elog_seen = max(self._elog_seen, entries[-1].seqnum)
        return [e for e in new if e.msgtype == rp.ELOG_ERROR]

    def read_joints(self) -> Array:
        st = self.get_state(f"rw/motionsystem/mechunits/{self.mechunit}/jointtarget",
                            "ms-jointtarget")
        return np.radians(rp.numbers(st, rp.RAX[:self.robot.dof], "jointtarget"))

    def current_pose(self) -> Array:
        """The TCP of our model's tool: the controller's tool0 (flange) pose, counted from its
        base (the robot's program frame), in our model base, times our tool."""
        st = self.get_state(f"rw/motionsystem/mechunits/{self.mechunit}/robtarget?tool=tool0"
                            "&wobj=wobj0&coordinate=Base", "ms-robtargets")
        T = rp.pose_from(rp.numbers(st, ("x", "y", "z"), "robtarget"),
                         rp.numbers(st, ("q1", "q2", "q3", "q4"), "robtarget"))
        return np.asarray(self.robot.program_frame()[0]) @ T @ self.robot.T_flange_tool

    def request_mastership(self) -> None:
        self.request("POST", self.rws.mastership("request"), {}, timeout_s=self.load_timeout_s)

    def release_mastership(self) -> None:
        self.request("POST", self.rws.mastership("release"), {}, timeout_s=self.load_timeout_s)

    def system(self) -> dict:
        """The controller's name and RobotWare version (``/rw/system``)."""
        return self.get_state("rw/system", "sys-system")

    # ------------------------------------------------------------------ RobotLink
    def connect(self) -> None:
        self._connected = False
        self._unsubscribe()
        if any(True for _ in getattr(self, "_cookies", ())):
            # The old session may still hold mastership (a reply lost mid-load): end it.
            with contextlib.suppress(LinkError):
                self.request("GET", "logout", json=False)
        self._opener = self._new_opener()  # a new session: the old one may be gone
        state = self.controller_state()
        if state == "motoroff":
            self.request("POST", *self.rws.set_ctrlstate("motoron"))
            state = self.controller_state()
        if state != "motoron":
            raise LinkError(f"controller is in state {state!r}; it must be 'motoron'")
        mode = self.operation_mode()
        if mode.upper() != "AUTO":
            raise LinkError(f"controller is in {mode} mode; RWS starts programs only in AUTO: "
                            "turn the mode key on the controller to Auto and confirm on the "
                            "FlexPendant")
        entries = self.event_log()
        self._elog_seen = entries[-1].seqnum if entries else 0
        self._last_q = self.read_joints()
        self._subscribe()
        self._connected = True

    def _subscribe(self) -> None:
        """The execution-state subscription; without one the link polls (and says so)."""
        self._unsubscribe()
        if not self.use_subscription:
            return
        try:
            form = subscription_form()
            v2 = self.rws.version == 2
            req = urllib.request.Request(
                f"{self.base_url}/subscription" + ("" if v2 else "?json=1"),
                data=urlencode(form).encode(), method="POST",
                headers={"Content-Type": V2_FORM if v2 else
                         "application/x-www-form-urlencoded",
                         **({"Accept": V2_JSON, "Authorization": self._basic()} if v2
                            else {})})
            self.wire.sent("http", f"POST {req.full_url} {urlencode(form)}")
            with self._lock, self._opener.open(req, timeout=self.timeout_s) as resp:
                body = resp.read().decode("utf-8", errors="replace")
                location = resp.headers.get("Location")
            self.wire.received("http", f"{resp.status} Location {location}")
            url = websocket_url(location, body)
            if url is None:
                raise OSError(f"no websocket address in {body[:200]!r}")
            cookie = "; ".join(f"{c.name}={c.value}" for c in self._cookies)
            headers = {"Cookie": cookie} if cookie else {}
            if self.rws.version == 2:
                headers["Authorization"] = self._basic()
            self.subscription = ExecutionSubscription(
                url, subprotocol=self.rws.subprotocol, headers=headers,
                timeout_s=self.timeout_s, tls=self._tls, wire=self.wire)
        except (OSError, urllib.error.URLError, http.client.HTTPException) as exc:
            self.subscription = None
            self.wire.note("subscription", f"not available, polling instead: {exc}")

    def _unsubscribe(self) -> None:
        if self.subscription is not None:
            self.subscription.close()
            self.subscription = None

    def close(self) -> None:
        self._unsubscribe()
        if self._connected:
            with contextlib.suppress(LinkError):
                self.request("GET", "logout", json=False)
        self._connected = False

    @property
    def connected(self) -> bool:
        return self._connected

    def current_joints(self) -> Array:
        if self._connected:
            self._last_q = self.read_joints()
        return self._last_q.copy()

    def stop(self) -> None:
        """Stop RAPID execution (allowed whoever holds mastership)."""
        self._stop.set()
        with contextlib.suppress(LinkError):
            self.request("POST", self.rws.execution("stop"), {"stopmode": "stop",
                                                              "usetsp": "normal"})

    # ------------------------------------------------------------------ programs
    def _load(self, files: dict[str, bytes]) -> list[str]:
        """Upload modules, unload ours from before, load these (under mastership)."""
        names = []
        for fname, data in files.items():
            if not fname.lower().endswith(MODULE_EXTENSIONS):
                raise LinkError(f"{fname}: only RAPID modules ({', '.join(MODULE_EXTENSIONS)})"
                                " can be loaded")
            name = rp.module_name(data.decode("utf-8", errors="replace"))
            if name is None:
                raise LinkError(f"{fname} has no MODULE line")
            names.append(name)
        for fname, data in files.items():
            self.request("PUT", f"fileservice/{self.home_dir}/{fname}", body=data, json=False,
                         timeout_s=self.load_timeout_s)
        self.request_mastership()
        try:
            for old in list(self.loaded):
                with contextlib.suppress(ControllerRefused):  # gone already (restart, user)
                    self.request("POST", *self.rws.unloadmod(self.task, old),
                                 timeout_s=self.load_timeout_s)
                self.loaded.remove(old)
            for fname in files:
                self.request("POST", *self.rws.loadmod(self.task, f"{self.home_dir}/{fname}"),
                             timeout_s=self.load_timeout_s)
                self.loaded.append(rp.module_name(files[fname].decode("utf-8", "replace"))
                                   or fname)
        finally:
            with contextlib.suppress(LinkError):
                self.release_mastership()
        return names

    def upload_program(self, name: str, files: dict[str, bytes]) -> str:
        """Upload and load the exported RAPID module(s); returns the main module's name.

        Its ``PROC main()`` is loaded as the routine ``ct_<module>``: the task keeps its own
        main. `run_program` sets the program pointer to that routine and starts it."""
        if not self._connected:
            raise LinkError("ABB link is not connected; call connect() first")
        texts = {f: d.decode("utf-8", errors="replace") for f, d in files.items()}
        mains = [f for f, t in texts.items() if rp.has_main(t)]
        if len(mains) != 1:
            raise LinkError(f"need exactly one module with PROC main(), got {mains or 'none'}")
        module = rp.module_name(texts[mains[0]]) or name
        routine = re.sub(r"\W", "_", f"ct_{module}")[:32]
        files = dict(files)
        files[mains[0]] = rp.main_as_routine(texts[mains[0]], routine).encode("utf-8")
        self._load(files)
        self.program = (module, routine)
        return module

    def run_program(self, name: str = "", *, wait: bool = True,
                    timeout_s: float = 600.0) -> LinkEvent:
        """Start the uploaded program's routine (cycle once); optionally wait for its end."""
        if not self._connected:
            raise LinkError("ABB link is not connected; call connect() first")
        if self.program is None:
            raise LinkError("no program uploaded: upload_program() first")
        if not self._moving.acquire(blocking=False):
            raise LinkError("the robot is already moving")
        try:
            self._stop.clear()
            self._pressed = None
            mark = self.subscription.mark() if self.subscription else 0
            try:
                self._start(*self.program)
            except ControllerRefused as exc:
                return self._event(LinkEventKind.ERROR, str(exc), 0, {"code": exc.code})
            if not wait:
                return LinkEvent(LinkEventKind.MOVED, self._last_q.copy(), time.monotonic(),
                                 f"{name or 'program'} started")
            return self._watch(None, None, 0, timeout_s, f"{name or 'program'} finished", mark)
        finally:
            self._moving.release()

    def _start(self, module: str, routine: str) -> None:
        self.new_errors()  # baseline: only errors of this run count
        self.request("POST", *self.rws.set_pp_routine(self.task, module, routine),
                     timeout_s=self.load_timeout_s)
        self.request("POST", self.rws.execution("start"), dict(START_FORM))

    # ------------------------------------------------------------------ motions
    def plan_commands(self, joint_path: Array) -> tuple[Array, Array]:
        """The MoveAbsJ targets (K, dof) for a path and the path index of each (decimated)."""
        path = validate_path(self.robot, joint_path)
        return exact_stop_targets(path, self._last_q, self._radii, self.decimation_tol_m)

    def move_path(self, joint_path: Array, *, speed_scale: float = 1.0) -> LinkEvent:
        path = validate_path(self.robot, joint_path)
        time_parametrize(path[:1], self.robot.limits.velocity, speed_scale)  # checks the scale
        if not self._connected:
            raise LinkError("ABB link is not connected; call connect() first")
        if not self._moving.acquire(blocking=False):
            raise LinkError("the robot is already moving")
        try:
            self._stop.clear()
            self._pressed = None
            targets, index = self.plan_commands(path)
            self.last_command_count = len(targets)
            timed = time_parametrize(np.vstack([self._last_q[None], targets]),
                                     self.robot.limits.velocity, speed_scale)
            module = rp.joint_move_module(targets, speed_scale * self.joint_tcp_speed_mm_s)
            mark = self.subscription.mark() if self.subscription else 0
            try:
                self._load({f"{rp.MOVE_MODULE}.mod": module.encode()})
                self._start(rp.MOVE_MODULE, rp.MOVE_ROUTINE)
            except LinkLost as exc:
                return self._event(LinkEventKind.LINK_LOST, str(exc), 0)
            except (ControllerRefused, ProtocolError) as exc:
                return self._event(LinkEventKind.ERROR, str(exc), 0,
                                   {"code": getattr(exc, "code", ""), "raw": exc.raw})
            segments = np.vstack([self._last_q[None], targets])
            return self._watch(segments, index, len(path) - 1,
                               timed.duration * 1.5 + 2 * self.timeout_s, "reached", mark)
        finally:
            self._moving.release()

    def _running(self, mark: list[int], asked: list[float]) -> bool:
        """Is the program still running? A stop event after `mark` (confirmed by a read, as
        an old event may arrive late), else a direct read once a second; no subscription:
        a read every time."""
        sub = self.subscription
        if sub is None or not sub.alive:
            return self.execution_state() == "running"
        seq, state = sub.wait_change(mark[0], self.poll_period_s)
        if state is not None:
            mark[0] = seq
        if state == "stopped" or time.monotonic() - asked[0] > 1.0:
            asked[0] = time.monotonic()
            return self.execution_state() == "running"
        return True

    def _watch(self, segments: Array | None, index: Array | None, last: int,
               timeout_s: float, done: str, mark: int = 0) -> LinkEvent:
        """Follow the program until it stops; the event says why."""
        deadline = time.monotonic() + timeout_s
        k = 0
        stop_sent = False
        marks, asked = [mark], [time.monotonic()]
        while True:
            try:
                running = self._running(marks, asked)
                q_prev, self._last_q = self._last_q, self.read_joints()
                if np.max(np.abs(self._last_q - q_prev)) > MOVING_RAD:
                    # Still moving: reduced speed in manual mode or the override may stretch
                    # a move far past its planned time; only a standing program times out.
                    deadline = max(deadline, time.monotonic() + timeout_s)
                if segments is not None:
                    k = _segment(segments, self._last_q)
                pi = int(index[k]) if index is not None else 0
                if running:
                    self._emit(LinkEvent(LinkEventKind.MOVED, self._last_q.copy(),
                                         time.monotonic(), "running", pi))
                    if self._stop.is_set() and not stop_sent:
                        self.stop()
                        stop_sent = True
                    if time.monotonic() > deadline:
                        self.stop()
                        return self._event(LinkEventKind.ERROR, "program still running with "
                                           f"the arm standing for {timeout_s:.1f} s; stopped it",
                                           pi)
                    if self.subscription is None:
                        time.sleep(self.poll_period_s)
                    continue
                errors = self.new_errors()
            except LinkLost as exc:
                return self._event(LinkEventKind.LINK_LOST, str(exc),
                                   int(index[k]) if index is not None else 0)
            except (ProtocolError, ControllerRefused) as exc:
                self.stop()  # we cannot see the robot any more: do not let it run blind
                return self._event(LinkEventKind.ERROR, f"{exc}; program stopped",
                                   int(index[k]) if index is not None else 0,
                                   {"raw": exc.raw})
            return self._finished(errors, segments, pi, last, done)

    def _finished(self, errors: list[rp.ElogEntry], segments: Array | None, pi: int,
                  last: int, done: str) -> LinkEvent:
        hit = [e for e in errors if e.code in rp.COLLISION_CODES]
        details = {"elog": [e.describe() for e in errors]}
        if hit:
            details.update(source="controller", code=hit[0].code)
            return self._event(LinkEventKind.COLLISION_INDICATED,
                               f"collision: controller {hit[0].describe()}", pi, details)
        if errors:
            details["code"] = errors[0].code
            return self._event(LinkEventKind.ERROR, f"controller stopped the program: "
                               f"{errors[0].describe()}", pi, details)
        if self._stop.is_set():
            kind, text, details = self._stopped_as(details)
            return self._event(kind, text, pi, details)
        if segments is not None and not np.allclose(self._last_q, segments[-1], atol=1e-4):
            return self._event(LinkEventKind.ERROR, "program stopped before the target "
                               "without an event-log error", pi, details)
        return self._event(LinkEventKind.REACHED, done, last)

    def _event(self, kind: LinkEventKind, message: str, path_index: int,
               details: dict | None = None) -> LinkEvent:
        ev = LinkEvent(kind, self._last_q.copy(), time.monotonic(), message, path_index,
                       details or {})
        self._emit(ev)
        return ev


def _segment(points: Array, q: Array) -> int:
    """Index (0-based, into the targets) of the straight joint segment nearest q."""
    best, best_d = 0, np.inf
    for k in range(len(points) - 1):
        a, b = points[k], points[k + 1]
        d = b - a
        t = float(np.clip((q - a) @ d / max(float(d @ d), 1e-18), 0.0, 1.0))
        dist = float(np.linalg.norm(a + t * d - q))
        if dist < best_d - 1e-12:
            best, best_d = k, dist
    return best
