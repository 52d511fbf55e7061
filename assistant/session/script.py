"""Scripted sessions: a YAML list of operator actions, run headless through the same `Session`.

    cell: thesis_rv2aj        # optional: a sample cell name or a cell folder to start from
    with_objects: false       # also take the sample's placed objects (default: false)
    with_mission: false       # also take its taught locations and mission (default: false)
    actions:
      - next
      - import_cad: {file: parts/O1.dxf, name: O1, units: mm}
      - place: {object: O1, pose: [300, -120, 0, 0, 0, 0]}     # mm and degrees
      - teach_pointer: {name: P7, at: [320, -70, 80]}          # synthetic pointer dwell
      - plan
      - execute
      - export: {dialect: melfa}

Verbs are the `Session` methods; lengths are millimetres and angles degrees (the edge of the
product); a malformed script fails before anything runs, with its line number and the reason.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from assistant.cell.cad.importer import read_cad_file
from assistant.cell.model import ObjectRole
from assistant.file_guard import FileRefused, read_file
from assistant.links.settings import LinkSettings
from assistant.mission.motion import ToolAction, ToolActionKind
from assistant.robots.catalog import RobotSpec, ToolSpec
from assistant.session.session import Session
from assistant.session.types import HiddenObstacle
from assistant.transforms import pose_from_mm_deg

Array = np.ndarray


class ScriptError(ValueError):
    """A script that cannot run as written: `file:line: reason`."""


@dataclass(frozen=True)
class ScriptAction:
    verb: str
    args: dict[str, Any]
    line: int


@dataclass
class Script:
    path: Path
    actions: list[ScriptAction]
    cell: str | None = None
    with_objects: bool = False
    with_mission: bool = False
    header: dict[str, Any] = field(default_factory=dict)


# ------------------------------------------------------------------ argument helpers
def _mm(v: Any, n: int, what: str) -> Array:
    a = np.asarray(v, dtype=float)
    if a.shape != (n,) or not np.all(np.isfinite(a)):
        raise ValueError(f"{what} needs {n} numbers (mm{', deg' if n == 6 else ''})")
    return a


def _pose(v: Any, what: str = "pose") -> Array:
    return pose_from_mm_deg(_mm(v, 6, what))


def _point(v: Any, what: str = "point") -> Array:
    return _mm(v, 3, what) / 1000.0


_ACTION_WORDS = {
    "open": ToolAction(ToolActionKind.GRIPPER_OPEN),
    "close": ToolAction(ToolActionKind.GRIPPER_CLOSE),
}


def _actions(v: Any) -> list[ToolAction]:
    out = []
    for a in v or []:
        if isinstance(a, str) and a in _ACTION_WORDS:
            out.append(_ACTION_WORDS[a])
        elif isinstance(a, dict) and "wait_s" in a:
            out.append(ToolAction(ToolActionKind.WAIT, seconds=float(a["wait_s"])))
        elif isinstance(a, dict) and "output" in a:
            out.append(ToolAction(ToolActionKind.OUTPUT, channel=int(a["output"]),
                                  value=bool(a.get("value", True))))
        else:
            raise ValueError(f"unknown tool action {a!r} (open, close, {{wait_s: 0.5}}, "
                             "{output: 3, value: true})")
    return out


def _tool(d: dict) -> ToolSpec:
    return ToolSpec.straight(float(d.get("length_mm", 0.0)) / 1000.0,
                             float(d.get("radius_mm", 20.0)) / 1000.0,
                             name=str(d.get("name", "gripper")),
                             has_gripper=bool(d.get("gripper", True)))


# ------------------------------------------------------------------ verbs
def _choose_robot(s: Session, a: dict) -> Any:
    kind = a.get("kind", "rv2aj")
    tool = _tool(a["tool"]) if "tool" in a else ToolSpec()
    spec = RobotSpec(kind=kind, urdf_path=a.get("urdf"),
                     package_dirs=tuple(a.get("package_dirs", ())),
                     base_link=a.get("base_link"), tool_link=a.get("tool_link"), tool=tool)
    return s.choose_robot(spec)


def _link(s: Session, a: dict) -> Any:
    return s.set_link(LinkSettings.from_json(a))


def _hidden(s: Session, a: dict) -> Any:
    size = np.asarray(a["size"], float).reshape(-1) / 1000.0
    h = HiddenObstacle(str(a["name"]), str(a.get("kind", "box")), tuple(size),
                       _pose(a.get("pose", [0, 0, 0, 0, 0, 0])))
    return s.set_hidden_obstacles([*s.hidden, h])


def _import_cad(s: Session, a: dict, base: Path) -> Any:
    path = base / a["file"]
    if path.suffix.lower() == ".dxf" and path.is_file() and \
            s.read_layout(read_cad_file(path), path.name) is not None:
        if "pose" in a or "name" in a:
            raise ValueError(f"{a['file']} is a cell layout: its parts are placed and named as "
                             "drawn (no pose or name)")
        return s.import_layout_path(path, units=a.get("units"),
                                    role=ObjectRole(a.get("role", "obstacle")))
    T = _pose(a["pose"]) if "pose" in a else None
    height = a.get("extrude_mm")
    return s.import_cad_path(base / a["file"], name=a.get("name"), units=a.get("units"),
                             dxf_extrude_height=None if height is None else float(height) / 1000,
                             role=ObjectRole(a.get("role", "obstacle")), T_world_object=T)


def _add_primitive(s: Session, a: dict) -> Any:
    kind = a["kind"]
    size = np.asarray(a["size"], float) / 1000.0
    return s.add_primitive(kind, tuple(size), name=a.get("name"),
                           role=ObjectRole(a.get("role", "obstacle")),
                           T_world_object=_pose(a["pose"]) if "pose" in a else None)


def _place_by_points(s: Session, a: dict) -> Any:
    model = np.asarray(a["model"], float) / 1000.0
    measured = np.asarray(a["measured"], float) / 1000.0
    return s.fit_object_pose(a["object"], model, measured)


def _teach_pointer(s: Session, a: dict) -> Any:
    return s.teach_by_pointer_dwell(a["name"], _point(a["at"], "at"), seed=int(a.get("seed", 0)))


def _add_path(s: Session, a: dict) -> Any:
    kinds = [k for k in ("line", "arc", "bezier") if k in a]
    if len(kinds) != 1:
        raise ValueError("a path needs exactly one of line, arc, bezier")
    kind = kinds[0]
    pts = [p if isinstance(p, str) else _point(p) for p in a[kind]]
    return s.add_path(a["name"], kind, pts, before=_actions(a.get("before")),
                      after=_actions(a.get("after")),
                      speed=float(a.get("speed_mm_s", 50.0)) / 1000.0,
                      reversible=bool(a.get("reversible", False)),
                      approach=float(a.get("approach_mm", 0.0)) / 1000.0,
                      depart=float(a.get("depart_mm", 0.0)) / 1000.0)


def _frame_point(v: Any, what: str) -> Any:
    """A measured point: a taught location's name, or x, y, z in mm."""
    return v if isinstance(v, str) else _point(v, what)


def _calibrate_frame(s: Session, a: dict) -> Any:
    return s.calibrate_frame(a["name"], _frame_point(a["origin"], "origin"),
                             _frame_point(a["x_point"], "x_point"),
                             _frame_point(a["xy_point"], "xy_point"))


def _add_drawing(s: Session, a: dict) -> Any:
    kinds = [k for k in ("drawing", "points") if k in a]
    if len(kinds) != 1:
        raise ValueError("a drawing needs exactly one of drawing (1..9) or points (mm)")
    if "drawing" in a:
        drawing: Any = int(a["drawing"])
    else:
        drawing = np.asarray(a["points"], float) / 1000.0
    at = _mm(a.get("at", [0, 0]), 2, "at") / 1000.0
    return s.add_drawing(a["name"], a["frame"], drawing, at=(float(at[0]), float(at[1])),
                         angle=float(np.radians(float(a.get("angle_deg", 0.0)))),
                         lift=float(a.get("lift_mm", 30.0)) / 1000.0,
                         before=_actions(a.get("before")), after=_actions(a.get("after")),
                         speed=float(a.get("speed_mm_s", 50.0)) / 1000.0,
                         reversible=bool(a.get("reversible", False)),
                         tool_angle=float(np.radians(float(a.get("tool_angle_deg", 0.0)))))


def _jog(s: Session, a: dict) -> Any:
    if "joints_deg" in a:
        return s.jog_joints(np.radians(np.asarray(a["joints_deg"], float)))
    return s.jog_tcp(_pose(a["pose"]))


Verb = Callable[..., Any]

VERBS: dict[str, tuple[Verb, bool]] = {
    # verb: (function(session, args[, base_dir]), needs the script's folder)
    "choose_robot": (_choose_robot, False),
    "link": (_link, False),
    "hidden_obstacle": (_hidden, False),
    "next": (lambda s, a: s.next(), False),
    "previous": (lambda s, a: s.previous(), False),
    "goto": (lambda s, a: s.goto(a["step"]), False),
    "import_cad": (_import_cad, True),
    "add_primitive": (_add_primitive, False),
    "remove_object": (lambda s, a: s.remove_object(a["name"]), False),
    "place": (lambda s, a: s.place_object(a["object"], _pose(a["pose"])), False),
    "place_by_points": (_place_by_points, False),
    "calibrate_frame": (_calibrate_frame, False),
    "place_in_frame": (lambda s, a: s.place_object_in_frame(
        a["object"], a["frame"], _pose(a["pose"])), False),
    "teach": (lambda s, a: s.teach(a["name"], _pose(a["pose"])), False),
    "teach_pointer": (_teach_pointer, False),
    "teach_robot": (lambda s, a: s.teach_from_robot(a["name"]), False),
    "teach_cad_click": (lambda s, a: s.teach_from_cad_click(
        a["name"], _point(a["at"]), None if "normal" not in a else
        np.asarray(a["normal"], float)), False),
    "remove_location": (lambda s, a: s.remove_location(a["name"]), False),
    "set_start": (lambda s, a: s.set_start(a["name"]), False),
    "set_goal": (lambda s, a: s.set_goal(a["name"]), False),
    "add_path": (_add_path, False),
    "add_drawing": (_add_drawing, False),
    "remove_path": (lambda s, a: s.remove_path(a["name"]), False),
    "move_path": (lambda s, a: s.move_path(a["name"], int(a["index"])), False),
    "jog": (_jog, False),
    "world_settings": (lambda s, a: s.set_world_settings(**a), False),
    "build_world": (lambda s, a: s.build_world(), False),
    "explore": (lambda s, a: s.explore(a.get("mode", "random"), int(a.get("moves", 5)),
                                       seed=int(a.get("seed", 0))), False),
    "order_mission": (lambda s, a: s.order_mission(), False),
    "plan": (lambda s, a: s.plan(), False),
    "execute": (lambda s, a: s.execute(), False),
    "drive_final": (lambda s, a: s.drive_final(), False),
    "indicate_collision": (lambda s, a: s.indicate_collision(), False),
    "forget_indication": (lambda s, a: s.forget_indication(int(a["number"])), False),
    "export": (lambda s, a: s.export(a.get("dialect"), frame=a.get("frame")), False),
    "undo": (lambda s, a: s.undo(), False),
    "redo": (lambda s, a: s.redo(), False),
}

#: Keys each verb accepts (checked before the run starts).
ARGS: dict[str, set[str]] = {
    "choose_robot": {"kind", "tool", "urdf", "package_dirs", "base_link", "tool_link"},
    "link": set(LinkSettings().to_json()),
    "hidden_obstacle": {"name", "kind", "size", "pose"},
    "goto": {"step"},
    "import_cad": {"file", "name", "units", "role", "pose", "extrude_mm"},
    "add_primitive": {"kind", "size", "name", "role", "pose"},
    "remove_object": {"name"},
    "place": {"object", "pose"},
    "place_by_points": {"object", "model", "measured"},
    "calibrate_frame": {"name", "origin", "x_point", "xy_point"},
    "place_in_frame": {"object", "frame", "pose"},
    "teach": {"name", "pose"},
    "teach_pointer": {"name", "at", "seed"},
    "teach_robot": {"name"},
    "teach_cad_click": {"name", "at", "normal"},
    "remove_location": {"name"},
    "set_start": {"name"},
    "set_goal": {"name"},
    "add_path": {"name", "line", "arc", "bezier", "before", "after", "speed_mm_s",
                 "approach_mm", "depart_mm",
                 "reversible"},
    "add_drawing": {"name", "frame", "drawing", "points", "at", "angle_deg", "lift_mm",
                    "before", "after", "speed_mm_s", "reversible", "tool_angle_deg"},
    "remove_path": {"name"},
    "move_path": {"name", "index"},
    "jog": {"joints_deg", "pose"},
    "explore": {"mode", "moves", "seed"},
    "world_settings": {"resolution_mm", "joint_samples", "memory_mb", "store", "clearance_mm",
                       "max_indications", "planning_budget_s"},
    "forget_indication": {"number"},
    "export": {"dialect", "frame"},
}
REQUIRED: dict[str, set[str]] = {
    "goto": {"step"}, "import_cad": {"file"}, "add_primitive": {"kind", "size"},
    "remove_object": {"name"}, "place": {"object", "pose"},
    "place_by_points": {"object", "model", "measured"}, "teach": {"name", "pose"},
    "calibrate_frame": {"name", "origin", "x_point", "xy_point"},
    "place_in_frame": {"object", "frame", "pose"}, "add_drawing": {"name", "frame"},
    "teach_pointer": {"name", "at"}, "teach_robot": {"name"}, "teach_cad_click": {"name", "at"},
    "remove_location": {"name"}, "set_start": {"name"}, "set_goal": {"name"},
    "add_path": {"name"}, "remove_path": {"name"}, "move_path": {"name", "index"},
    "hidden_obstacle": {"name", "size"}, "forget_indication": {"number"},
}
#: A script longer than this is not one an operator wrote.
MAX_SCRIPT_BYTES = 16 * 2**20
#: Verbs whose single scalar argument may be written inline: `- set_start: P1`.
SCALAR_ARG = {"set_start": "name", "set_goal": "name", "goto": "step", "export": "dialect",
              "teach_robot": "name", "remove_object": "name", "remove_location": "name",
              "remove_path": "name"}


# ------------------------------------------------------------------ parsing
def parse_script(path: str | Path) -> Script:
    path = Path(path)
    try:
        text = read_file(path, limit=MAX_SCRIPT_BYTES, what="script").decode("utf-8")
    except FileRefused as exc:
        raise ScriptError(str(exc)) from None
    except UnicodeDecodeError as exc:
        raise ScriptError(f"{path}: not UTF-8 text ({exc.reason})") from None
    try:
        root = yaml.compose(text, Loader=yaml.SafeLoader)
    except yaml.YAMLError as exc:
        # The construct that failed to close (context) is where the operator must look.
        mark = getattr(exc, "context_mark", None) or getattr(exc, "problem_mark", None)
        line = mark.line + 1 if mark is not None else 0
        raise ScriptError(f"{path}:{line}: not valid YAML ({getattr(exc, 'problem', exc)})") \
            from None
    if root is None or not isinstance(root, yaml.MappingNode):
        raise ScriptError(f"{path}:1: a script is a mapping with an 'actions' list")
    header: dict[str, Any] = {}
    actions_node = None
    for key_node, value_node in root.value:
        key = key_node.value
        if key == "actions":
            actions_node = value_node
        elif key in ("cell", "with_objects", "with_mission", "version", "description"):
            header[key] = yaml.safe_load(yaml.serialize(value_node))
        else:
            raise ScriptError(f"{path}:{key_node.start_mark.line + 1}: unknown key {key!r} "
                              "(cell, with_objects, with_mission, version, description, "
                              "actions)")
    if actions_node is None or not isinstance(actions_node, yaml.SequenceNode):
        raise ScriptError(f"{path}:1: 'actions' must be a list of operator actions")
    actions = [_parse_action(path, node) for node in actions_node.value]
    return Script(path, actions, header.get("cell"), bool(header.get("with_objects", False)),
                  bool(header.get("with_mission", False)), header)


def _parse_action(path: Path, node: yaml.Node) -> ScriptAction:
    line = node.start_mark.line + 1
    value = yaml.safe_load(yaml.serialize(node))
    args: dict[str, Any]
    if isinstance(value, str):
        verb, args = value, {}
    elif isinstance(value, dict) and len(value) == 1:
        verb, raw = next(iter(value.items()))
        if raw is None:
            args = {}
        elif isinstance(raw, dict):
            args = raw
        elif verb in SCALAR_ARG:
            args = {SCALAR_ARG[verb]: raw}
        else:
            raise ScriptError(f"{path}:{line}: arguments of {verb!r} must be a mapping")
    else:
        raise ScriptError(f"{path}:{line}: an action is a verb or a one-key mapping "
                          "(e.g. '- plan' or '- teach: {name: P1, pose: [...]}')")
    if verb not in VERBS:
        raise ScriptError(f"{path}:{line}: unknown action {verb!r}; known: "
                          f"{', '.join(sorted(VERBS))}")
    allowed = ARGS.get(verb, set())
    extra = sorted(set(args) - allowed)
    if extra:
        raise ScriptError(f"{path}:{line}: {verb} does not take {', '.join(extra)}"
                          + (f" (takes {', '.join(sorted(allowed))})" if allowed else ""))
    missing = sorted(REQUIRED.get(verb, set()) - set(args))
    if missing:
        raise ScriptError(f"{path}:{line}: {verb} needs {', '.join(missing)}")
    return ScriptAction(verb, args, line)


def run_action(session: Session, action: ScriptAction, base_dir: Path, script_path: Path) -> Any:
    fn, needs_dir = VERBS[action.verb]
    try:
        return fn(session, action.args, base_dir) if needs_dir else fn(session, action.args)
    except ScriptError:
        raise
    except Exception as exc:
        raise ScriptError(f"{script_path}:{action.line}: {action.verb} failed: {exc}") from exc


def run_script(script: Script, folder: Path | None, *,
               stop_before: str | tuple[str, ...] = (),
               ) -> tuple[Session, str | None]:
    """A session built as the script says (its sample cell or empty; saved in `folder`, None:
    not saved) with its actions run in order, and the first error as one line (None: all
    ran). `stop_before` ends the run at the first action with that verb or one of those
    verbs (e.g. "export", to export in another dialect).

    Raises ValueError/OSError when the script's cell cannot be loaded."""
    if script.cell:
        base = script.path.parent
        cell = script.cell if not (base / script.cell).is_dir() else base / script.cell
        session = Session.from_sample(cell, folder, with_objects=script.with_objects,
                                      with_mission=script.with_mission)
    else:
        session = Session(folder)
    stops = (stop_before,) if isinstance(stop_before, str) else stop_before
    for action in script.actions:
        if action.verb in stops:
            break
        try:
            run_action(session, action, script.path.parent, script.path)
        except ScriptError as exc:
            return session, str(exc)
        except Exception as exc:  # noqa: BLE001 - reported in one line, never a traceback
            why = str(exc) or ("ran out of memory" if isinstance(exc, MemoryError)
                               else type(exc).__name__)
            return session, f"{script.path}:{action.line}: {action.verb} failed: {why}"
    return session, None
