"""Every wrong session target is one clear message, never a traceback: a zip or a plain
file given as the folder, wrong JSON types (named with what they should be), a newer
schema; unknown keys are reported and the rest loads."""

from __future__ import annotations

import json
import subprocess
import sys
import zipfile

import pytest

from assistant.session import Session
from assistant.session.store import SESSION_JSON, SessionFileError


@pytest.fixture(scope="module")
def saved(tmp_path_factory):
    folder = tmp_path_factory.mktemp("saved")
    Session.from_sample("thesis_rv2aj", folder).save(folder)
    return folder


def _copy(saved, tmp_path, edit):
    import shutil

    dst = tmp_path / "s"
    shutil.copytree(saved, dst)
    doc = json.loads((dst / SESSION_JSON).read_text())
    edit(doc)
    (dst / SESSION_JSON).write_text(json.dumps(doc))
    return dst


def test_a_zip_or_a_file_is_refused_with_what_to_give_instead(saved, tmp_path):
    z = tmp_path / "cell.zip"
    with zipfile.ZipFile(z, "w") as f:
        f.write(saved / SESSION_JSON, SESSION_JSON)
    with pytest.raises(SessionFileError, match="is a zip file, not a session folder"):
        Session.load(z)
    plain = tmp_path / "notes.txt"
    plain.write_text("x")
    with pytest.raises(SessionFileError, match="is a file, not a session folder"):
        Session.load(plain)


@pytest.mark.parametrize(("key", "value", "want"), [
    ("locations", {"P1": 1}, "'locations' should be a list"),
    ("mission", [], "'mission' should be an object"),
    ("robot_joints", "zero", "'robot_joints' should be a list or null"),
    ("export_dialect", 3, "'export_dialect' should be a string"),
    ("counters", True, "'counters' should be an object"),
])
def test_wrong_types_are_named(saved, tmp_path, key, value, want):
    bad = _copy(saved, tmp_path, lambda d: d.__setitem__(key, value))
    with pytest.raises(SessionFileError, match=want):
        Session.load(bad)


def test_unknown_keys_are_reported_and_the_rest_loads(saved, tmp_path):
    odd = _copy(saved, tmp_path, lambda d: d.update(misson={}, future_thing=1))
    s = Session.load(odd)
    assert sorted(n.split("unknown key ")[1] for n in s.load_notes) == \
        ["'future_thing' ignored", "'misson' ignored"]
    assert s.mission.to_json() == Session.load(saved).mission.to_json()


def test_a_newer_schema_is_refused(saved, tmp_path):
    newer = _copy(saved, tmp_path, lambda d: d.__setitem__("schema_version", 99))
    with pytest.raises(SessionFileError, match="schema version 99 is not supported"):
        Session.load(newer)


def test_serve_with_a_zip_says_so_and_exits_2(saved, tmp_path):
    z = tmp_path / "some_cell.zip"
    with zipfile.ZipFile(z, "w") as f:
        f.write(saved / SESSION_JSON, SESSION_JSON)
    out = subprocess.run([sys.executable, "-m", "assistant", "serve", "--session", str(z),
                          "--port", "0"], capture_output=True, text=True, timeout=120)
    assert out.returncode == 2
    assert "is a zip file, not a session folder" in out.stderr
    assert "Traceback" not in out.stderr
