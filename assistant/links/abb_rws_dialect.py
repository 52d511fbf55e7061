"""Where RWS 1.0 (IRC5, RobotWare 6) and RWS 2.0 (OmniCore, RobotWare 7) put things.

Both expose the same controller; they differ in transport and shape (ABB's "Robot Web
Services" application manual 3HAC050973-001 for 1.0, the OmniCore RWS 2.0 reference for 2.0),
RWS 1.0 | RWS 2.0:

- transport: HTTP on port 80 | HTTPS on 443 with the controller's self-signed certificate;
- login: HTTP digest | HTTP Basic; then the session cookie on both;
- format: ``?json=1`` on every request and ``{"_embedded": {"_state": [...]}}`` |
  ``Accept: application/hal+json;v=2.0`` and ``{"state": [...]}``;
- forms: ``application/x-www-form-urlencoded`` | the same with ``;v=2.0``;
- actions: in the query (``/rw/rapid/execution?action=start``) | in the path
  (``/rw/rapid/execution/start``);
- controller state: ``/rw/panel/ctrlstate`` (``?action=setctrlstate``) |
  ``/rw/panel/ctrl-state``;
- mastership: ``/rw/mastership?action=request`` | ``/rw/mastership/edit/request``;
- load a module: ``/rw/rapid/tasks/T_ROB1?action=loadmod`` | ``.../T_ROB1/loadmod``;
- program pointer to a routine: ``/rw/rapid/tasks/T_ROB1/pcp?action=set-pp-routine`` |
  ``.../pcp/routine``;
- subscription websocket: subprotocol ``robapi2_subscription`` | ``rws_subscription``.

An error is a 4xx whose JSON carries ``status`` (``{"code": ..., "msg": ...}``; under
``_embedded`` on 1.0). `Rws` gives the request for each operation the link uses; the
emulator routes both dialects onto one controller with `v2_to_v1`.
"""

from __future__ import annotations

from dataclasses import dataclass

Form = dict[str, str]
V2_JSON = "application/hal+json;v=2.0"
V2_FORM = "application/x-www-form-urlencoded;v=2.0"
START_FORM = {"regain": "continue", "execmode": "continue", "cycle": "once",
              "condition": "none", "stopatbp": "disabled", "alltaskbytsp": "false"}


@dataclass(frozen=True)
class Rws:
    version: int = 1

    def __post_init__(self) -> None:
        if self.version not in (1, 2):
            raise ValueError(f"RWS version {self.version} is not 1 (IRC5) or 2 (OmniCore)")

    @property
    def scheme(self) -> str:
        return "https" if self.version == 2 else "http"

    @property
    def default_port(self) -> int:
        return 443 if self.version == 2 else 80

    @property
    def subprotocol(self) -> str:
        return "rws_subscription" if self.version == 2 else "robapi2_subscription"

    def _act(self, resource: str, action: str) -> str:
        return f"{resource}/{action}" if self.version == 2 else f"{resource}?action={action}"

    def ctrlstate(self) -> str:
        return "rw/panel/ctrl-state" if self.version == 2 else "rw/panel/ctrlstate"

    def set_ctrlstate(self, state: str) -> tuple[str, Form]:
        path = self.ctrlstate() if self.version == 2 else \
            "rw/panel/ctrlstate?action=setctrlstate"
        return path, {"ctrl-state": state}

    def mastership(self, action: str) -> str:
        return f"rw/mastership/edit/{action}" if self.version == 2 else \
            f"rw/mastership?action={action}"

    def loadmod(self, task: str, path: str) -> tuple[str, Form]:
        return self._act(f"rw/rapid/tasks/{task}", "loadmod"), {"modulepath": path,
                                                                 "replace": "true"}

    def unloadmod(self, task: str, module: str) -> tuple[str, Form]:
        return self._act(f"rw/rapid/tasks/{task}", "unloadmod"), {"module": module}

    def set_pp_routine(self, task: str, module: str, routine: str) -> tuple[str, Form]:
        form = {"module": module, "routine": routine, "userlevel": "false"}
        if self.version == 2:
            return f"rw/rapid/tasks/{task}/pcp/routine", form
        return f"rw/rapid/tasks/{task}/pcp?action=set-pp-routine", form

    def execution(self, action: str) -> str:
        return self._act("rw/rapid/execution", action)


def v2_to_v1(path: str) -> tuple[str, str | None]:
    """An RWS 2.0 action path as (RWS 1.0 resource path, action); GETs map resources only.

    ``/rw/rapid/execution/start`` -> (``/rw/rapid/execution``, ``start``); an unknown path is
    returned unchanged with no action."""
    p = path.rstrip("/")
    if p == "/rw/panel/ctrl-state":
        return "/rw/panel/ctrlstate", None
    tails = {"/rw/rapid/execution/": ("start", "stop", "resetpp"),
             "/rw/mastership/edit/": ("request", "release")}
    for head, actions in tails.items():
        if p.startswith(head) and p[len(head):] in actions:
            base = "/rw/mastership" if head.startswith("/rw/mastership") else head.rstrip("/")
            return base, p[len(head):]
    parts = p.split("/")
    if len(parts) == 6 and parts[1:4] == ["rw", "rapid", "tasks"] and \
            parts[5] in ("loadmod", "unloadmod", "activate", "deactivate"):
        return "/".join(parts[:5]), parts[5]
    if len(parts) == 7 and parts[1:4] == ["rw", "rapid", "tasks"] and \
            parts[5:] == ["pcp", "routine"]:
        return "/".join(parts[:6]), "set-pp-routine"
    return path, None
