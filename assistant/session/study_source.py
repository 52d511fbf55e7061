"""A session to study (`cellteach study`): from a saved session folder, a sample cell or a
session script. Above the `Session` and its scripts, which it builds from."""

from __future__ import annotations

from pathlib import Path

from assistant.session.script import parse_script, run_script
from assistant.session.session import Session
from assistant.session.store import SESSION_JSON

#: Verbs a script runs before a study (the rest - building, planning, executing,
#: exporting - is what the study does per candidate, or comes after).
_STUDY_STOP_VERBS = ("build_world", "explore", "plan", "execute", "resume", "export")


def load_for_study(path: str | Path) -> Session:
    """A session to study from a saved session folder, a sample cell (name or folder) or a
    session script (run up to its first build/plan/execute/export). Raises ValueError with
    the reason."""
    p = Path(path)
    if p.is_dir() and (p / SESSION_JSON).exists():
        return Session.load(p)
    if p.suffix.lower() in (".yaml", ".yml") and p.is_file():
        s, error = run_script(parse_script(p), None, stop_before=_STUDY_STOP_VERBS)
        if error is not None:
            raise ValueError(error)
        return s
    return Session.from_sample(str(path), None)
