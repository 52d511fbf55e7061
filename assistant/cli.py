"""The `cellteach` command line (also `python -m assistant`).

    cellteach                          serve the default sample cell at http://127.0.0.1:8080
    cellteach serve [--cell NAME|PATH] [--session DIR] [--empty] [--host H] [--port P]
                    [--max-upload-mb N] [--token-file F] [--certfile C [--keyfile K]]
    cellteach run SCRIPT.yaml --out DIR
    cellteach study placement SESSION_OR_SCRIPT --region X0,Y0,X1,Y1 --step MM --out DIR
    cellteach cells
    cellteach emulate {ur,abb,omnicore,kuka,melfa} [--remote] [--host H] [--any-port]
    cellteach check-link {ur,abb,omnicore,kuka,melfa} HOST [--port P] [--user U]

Exit codes: 0 ok, 1 the session ran but failed (report.json says why) or a link check
failed, 2 bad input.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

DEFAULT_PORT = 8080
#: web.uploads.DEFAULT_MAX_UPLOAD_MB, written again: importing `web` here would load viser
#: for every command.
DEFAULT_MAX_UPLOAD_MB = 200.0


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="cellteach",
        description="Program an industrial robot in minutes: web assistant and headless runs.")
    sub = p.add_subparsers(dest="command")
    serve = sub.add_parser("serve", help="start the web UI (the default command)")
    _serve_args(serve)
    run = sub.add_parser("run", help="run a scripted session headless")
    run.add_argument("script", type=Path, help="the session script (YAML)")
    run.add_argument("--out", type=Path, required=True,
                     help="folder for the program files, report.json and the session")
    sub.add_parser("cells", help="list the sample cells")
    _study_args(sub)
    _link_args(sub)
    _serve_args(p)  # `cellteach --port 9000` works without the word serve
    return p


def _serve_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("--cell", default=None,
                   help="sample cell name or folder (default: thesis_rv2aj)")
    p.add_argument("--session", type=Path, default=None,
                   help="session folder: resumed if it holds a session, else created "
                        "(autosaved after every action)")
    p.add_argument("--empty", action="store_true",
                   help="take only the sample's robot, link and cameras: import and teach "
                        "everything yourself")
    p.add_argument("--host", default="127.0.0.1",
                   help="interface to listen on (default 127.0.0.1: this computer only, no "
                        "login); any other address asks for the printed access code")
    p.add_argument("--port", type=int, default=DEFAULT_PORT)
    p.add_argument("--max-upload-mb", type=float, default=DEFAULT_MAX_UPLOAD_MB,
                   help="largest upload (default %(default)s MB: a binary STL of the "
                        "4 M triangles a CAD import takes)")
    p.add_argument("--token-file", type=Path, default=None,
                   help="keep the access codes here (operator, then viewer; created if "
                        "missing, mode 0600) so they survive a restart")
    p.add_argument("--certfile", type=Path, default=None, help="serve HTTPS with this "
                   "certificate (PEM)")
    p.add_argument("--keyfile", type=Path, default=None,
                   help="the certificate's private key (PEM), if not in --certfile")


def _study_args(sub: argparse._SubParsersAction) -> None:
    study = sub.add_parser("study", help="studies of the cell (placement)")
    kinds = study.add_subparsers(dest="study", required=True)
    pl = kinds.add_parser("placement", help="where should the robot base (or an object) "
                          "stand: candidates over a region, ranked, study.json + a PNG map")
    pl.add_argument("source", help="a session folder, a sample cell (name or folder) or a "
                    "session script (run up to its first build_world/plan)")
    pl.add_argument("--region", required=True, help="X0,Y0,X1,Y1 in mm (world frame)")
    pl.add_argument("--step", type=float, required=True, help="grid step in mm")
    pl.add_argument("--yaw-steps", type=int, default=1, help="yaws per position, evenly "
                    "around the circle from the current yaw's 0 (default 1: yaw 0)")
    pl.add_argument("--out", type=Path, required=True, help="folder for study.json and "
                    "placement.png")
    pl.add_argument("--object", default=None, help="study this object's placement instead "
                    "of the robot base (taught locations on it move with it)")
    pl.add_argument("--margin-deg", type=float, default=5.0,
                    help="margin to the joint limits at every location (default 5)")
    pl.add_argument("--clearance-mm", type=float, default=None,
                    help="clearance a transfer should keep (default: the session's, 10)")
    pl.add_argument("--plan-top", type=int, default=16, help="plan this many of the best "
                    "screened candidates fully (default 16)")
    pl.add_argument("--workers", type=int, default=0, help="worker processes (default: every "
                    "core)")
    pl.add_argument("--ray", default=None, metavar="ADDRESS", help="run the tasks on Ray: "
                    "'local' starts one here, else a cluster address ('auto', ray://...)")
    pl.add_argument("--inline", action="store_true", help="run in this process (no workers)")


#: `cellteach` vendor words -> link kinds.
LINK_KINDS = {"ur": "ur", "abb": "abb", "omnicore": "omnicore", "kuka": "kuka_rest",
              "melfa": "melfa"}


def _link_args(sub: argparse._SubParsersAction) -> None:
    em = sub.add_parser("emulate", help="run a controller emulator on its usual ports "
                        "(prints one 'name host:port' line each; Ctrl-C stops it)")
    em.add_argument("vendor", choices=tuple(LINK_KINDS))
    em.add_argument("--host", default="127.0.0.1")
    em.add_argument("--remote", action="store_true", help="UR: start in Remote control "
                    "(a shipped e-Series starts in Local)")
    em.add_argument("--local-mode", action="store_true",
                    help="UR: start in Local control (the default, as shipped)")
    em.add_argument("--any-port", action="store_true", help="free ports instead of the "
                    "vendor's usual ones")
    em.add_argument("--time-scale", type=float, default=1.0)
    ck = sub.add_parser("check-link", help="pre-flight checklist of a robot link: one line "
                        "per item with what to do; exit 0 only if all pass")
    ck.add_argument("vendor", choices=tuple(LINK_KINDS))
    ck.add_argument("host")
    ck.add_argument("--port", type=int, default=None,
                    help="the controller's port (ABB 80, OmniCore 443, KUKA bridge 8000, "
                         "MELFA 10001); UR: the dashboard port, the others follow it "
                         "(29999 -> 30001..30004)")
    ck.add_argument("--user", default="Default User", help="ABB: the RWS user")
    ck.add_argument("--log-dir", type=Path, default=None, help="write the wire log here")


def cmd_emulate(args: argparse.Namespace) -> int:
    from assistant.emulators.launch import start
    from assistant.emulators.until_stopped import install_stop_handlers, wait_until_stopped

    if args.remote and args.local_mode:
        print("cellteach: --remote and --local-mode exclude each other", file=sys.stderr)
        return 2
    try:
        running = start(args.vendor, host=args.host, remote=args.remote,
                        any_port=args.any_port, time_scale=args.time_scale)
    except (OSError, FileNotFoundError) as exc:
        print(f"cellteach: cannot start the {args.vendor} emulator: {exc} (a port taken? "
              "--any-port picks free ones)", file=sys.stderr)
        return 2
    try:
        install_stop_handlers()
        for line in running.lines():
            print(line, flush=True)
        wait_until_stopped()
    finally:
        running.close()
    return 0


def cmd_check_link(args: argparse.Namespace) -> int:
    import os

    from assistant.links.checklist import check_link
    from assistant.links.settings import LinkSettings, LinkSettingsError

    kind = LINK_KINDS[args.vendor]
    kw: dict = {"kind": kind, "host": args.host}
    if kind == "ur":
        if args.port is not None:
            base = args.port
            kw.update(ur_dashboard_port=base, ur_primary_port=base + 2,
                      ur_script_port=base + 3, ur_rtde_port=base + 5)
    else:
        kw["port"] = args.port or {"abb": 80, "omnicore": 443, "kuka_rest": 8000,
                                   "melfa": 10001}[kind]
    if kind in ("abb", "omnicore"):
        kw["rws_user"] = args.user
        kw["rws_password"] = os.environ.get("CELLTEACH_RWS_PASSWORD", "robotics")
    try:
        settings = LinkSettings(**kw)
    except LinkSettingsError as exc:
        print(f"cellteach: {exc}", file=sys.stderr)
        return 2
    result = check_link(settings, log_dir=args.log_dir)
    print(result.text(), flush=True)
    return 0 if result.passed else 1


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        if args.command == "emulate":
            return cmd_emulate(args)
        if args.command == "check-link":
            return cmd_check_link(args)
        if args.command == "study":
            return cmd_study(args)
        if args.command == "run":
            return cmd_run(args.script, args.out)
        if args.command == "cells":
            return cmd_cells()
        return cmd_serve(args)
    except KeyboardInterrupt:
        return 130


def cmd_cells() -> int:
    from assistant.cell.samples import list_samples, samples_root

    samples = list_samples()
    if not samples:
        print(f"no sample cells under {samples_root()}", file=sys.stderr)
        return 1
    width = max(len(s.name) for s in samples)
    for s in samples:
        print(f"{s.name:<{width}}  {s.description}")
    return 0


def _default_session_dir() -> Path:
    return Path.home() / ".local" / "share" / "cellteach" / "sessions" / \
        time.strftime("%Y%m%d-%H%M%S")


def open_session(cell: str | None, folder: Path | None, empty: bool):
    """Resume `folder` if it holds a session, else start one on the sample cell."""
    from assistant.cell.samples import DEFAULT_SAMPLE
    from assistant.session import Session
    from assistant.session.store import SESSION_JSON

    if folder is not None and (folder.is_file() or (folder / SESSION_JSON).exists()):
        return Session.load(folder)  # a file is refused there with what to give instead
    folder = folder or _default_session_dir()
    return Session.from_sample(cell or DEFAULT_SAMPLE, folder, with_objects=not empty,
                               with_mission=not empty)


def cmd_serve(args: argparse.Namespace) -> int:
    from assistant.cell.samples import SampleError
    from assistant.kernels import lazy
    from assistant.session.store import SessionFileError

    # Before the session opens: opening one poses the robot and checks its home posture,
    # which on a first run would otherwise compile those kernels here (~10 s).
    compiling = lazy.start()
    try:
        session = open_session(args.cell, args.session, args.empty)
    except (SampleError, SessionFileError, ValueError, OSError) as exc:
        print(f"cellteach: {exc}", file=sys.stderr)
        return 2
    for note in session.load_notes:
        print(f"cellteach: {note}", file=sys.stderr)
    from web.app import serve
    from web.gate import AccessTokens, GateConfig, Role, TokenFileError, is_loopback

    gate = None
    if not is_loopback(args.host) or args.token_file or args.certfile or args.keyfile:
        try:
            tokens = AccessTokens.from_file(args.token_file) if args.token_file else \
                AccessTokens.new()
            gate = GateConfig(args.host, args.port, tokens, args.certfile, args.keyfile)
            gate.ssl_context()  # a wrong certificate or key is named before anything runs
        except (TokenFileError, ValueError) as exc:
            session.close()
            print(f"cellteach: {exc}", file=sys.stderr)
            return 2
    if compiling:
        print("cellteach: first run after an install: compiling the fast kernels in the "
              "background (a few minutes); everything works meanwhile", file=sys.stderr)
    try:
        app = serve(session, host=args.host, port=args.port, max_upload_mb=args.max_upload_mb,
                    gate=gate)
    except (OSError, ValueError) as exc:
        session.close()
        print(f"cellteach: {exc}", file=sys.stderr)
        return 2
    print(f"cellteach: serving {session.sample or 'a session'} at {app.url}", file=sys.stderr)
    if app.access is not None:
        # The codes: printed here once, never logged, never put in an address (a browser
        # keeps every address in its history): the page asks for them.
        print(f"cellteach: open {app.url}/ and enter an access code:", file=sys.stderr)
        print(f"cellteach: operator code (can move the robot): "
              f"{app.access.code(Role.OPERATOR)}", file=sys.stderr)
        print(f"cellteach: viewer code (watch only):           "
              f"{app.access.code(Role.VIEWER)}", file=sys.stderr)
        if gate is not None and gate.exposed and not gate.tls:
            print("cellteach: WARNING: the connection is not encrypted: anyone on this network "
                  "can read the page and the codes; use --certfile/--keyfile", file=sys.stderr)
    print(f"cellteach: session folder {session.folder} (autosaved)", file=sys.stderr)
    try:
        while True:
            time.sleep(3600)
    finally:
        app.stop()


def cmd_run(script_path: Path, out: Path) -> int:
    from assistant.session.report import session_report
    from assistant.session.script import ScriptError, parse_script, run_script

    t0 = time.perf_counter()
    try:
        script = parse_script(script_path)
    except ScriptError as exc:
        print(f"cellteach: {exc}", file=sys.stderr)
        return 2
    out.mkdir(parents=True, exist_ok=True)
    folder = out / "session"
    # No action waits on a compile: on the first run after an install the kernels run their
    # fallbacks while a background process compiles them into the cache.
    from assistant.kernels import lazy

    lazy.start()
    try:
        session, error = run_script(script, folder)
    except (ValueError, OSError) as exc:
        print(f"cellteach: {script_path}: {exc}", file=sys.stderr)
        return 2
    files: list[str] = []
    if session.program is not None:
        for f in session.program.files:
            (out / f.name).write_bytes(f.data)
            files.append(f.name)
    if session.save_error and error is None:
        error = f"the session could not be saved to {folder}: {session.save_error}"
    report = session_report(session, wall_time_s=time.perf_counter() - t0, error=error,
                            program_files=files)
    (out / "report.json").write_text(json.dumps(report, indent=1), encoding="utf-8")
    session.worker.join(5.0)
    if error is not None:
        print(f"cellteach: {error}", file=sys.stderr)
        return 1
    if not report["collision_free"] or not report["within_limits"]:
        print(f"cellteach: the final program is not safe: {report.get('collision', '')}",
              file=sys.stderr)
        return 1
    print(f"cellteach: wrote {', '.join(files) or 'no program'} and report.json to {out}",
          file=sys.stderr)
    return 0


def cmd_study(args: argparse.Namespace) -> int:
    """`cellteach study placement`: 0 a candidate was planned, 1 none was (study.json says
    why each failed), 2 bad input."""
    from assistant.progress import Cancelled, Progress
    from assistant.session.study_source import load_for_study
    from assistant.study import Region, StudySettings, run_study
    from assistant.study.picture import render_map

    try:
        region = Region.from_mm(args.region, args.step, args.yaw_steps)
        engine = "ray" if args.ray else "inline" if args.inline else "local"
        settings = StudySettings(plan_top=args.plan_top, engine=engine, workers=args.workers,
                                 ray_address=args.ray or "local")
        session = load_for_study(args.source)
        problem = session.study_problem(object_name=args.object,
                                        joint_margin_deg=args.margin_deg,
                                        clearance_mm=args.clearance_mm)
    except (ValueError, OSError) as exc:
        print(f"cellteach: {exc}", file=sys.stderr)
        return 2
    last = [-1.0]

    def show(ev) -> None:
        if ev.fraction - last[0] >= 0.1 or ev.fraction >= 1.0:
            last[0] = ev.fraction
            print(f"cellteach: study {ev.fraction * 100:3.0f} % {ev.message}", file=sys.stderr)

    try:
        result = run_study(problem, region, settings, Progress("placement study", show))
    except (RuntimeError, ValueError) as exc:  # e.g. Ray missing or unreachable
        print(f"cellteach: {exc}", file=sys.stderr)
        return 2
    except Cancelled:
        return 130
    finally:
        session.close()
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "study.json").write_text(json.dumps(result.to_json(), indent=1),
                                         encoding="utf-8")
    render_map(result, args.out / "placement.png")
    best = result.best()
    c = result.counts
    print(f"cellteach: {c['candidates']} candidates, {c['screened_ok']} passed the screen, "
          f"{c['planned_ok']} of {c['planned']} planned in {result.timings['total_s']:.1f} s; "
          f"wrote study.json and placement.png to {args.out}", file=sys.stderr)
    if best is None:
        print("cellteach: no candidate could be planned (see the reasons in study.json)",
              file=sys.stderr)
        return 1
    print(f"cellteach: best {best.candidate.label()}", file=sys.stderr)
    return 0
