"""What is saved and how: link passwords only in a 0600 secrets.json (never session.json, and
an old session.json that had one is cleaned on load); every file fsynced with its folder after
the rename; a disk that refuses a save keeps the change in memory and says "not saved" until a
later save works."""

from __future__ import annotations

import json
import os
import stat

import pytest

from assistant.links.settings import LinkSettings
from assistant.session import Session
from assistant.session.events import ErrorRaised, SaveStateChanged
from assistant.session.link_secrets import MASK, SECRETS_JSON, masked
from assistant.session.store import SessionFileError
from assistant.transforms import pose_from_mm_deg

PASSWORD = "Rws-pa55word-of-this-cell"


def _abb(s: Session) -> None:
    s.set_link(LinkSettings(kind="abb", host="192.0.2.7", port=80, rws_user="op",
                            rws_password=PASSWORD))


def _mode(path) -> int:
    return stat.S_IMODE(os.stat(path).st_mode)


def test_a_link_password_is_kept_apart_in_a_private_file(empty_session):
    s = empty_session
    _abb(s)
    text = (s.folder / "session.json").read_text()
    assert PASSWORD not in text and "rws_password" not in text
    assert json.loads(text)["link"]["rws_user"] == "op"
    secrets = s.folder / SECRETS_JSON
    assert _mode(secrets) == 0o600 and PASSWORD in secrets.read_text()
    back = Session.load(s.folder)
    assert back.link_settings.rws_password == PASSWORD and back.load_notes == []
    # Nothing else in the folder holds it (the cell, the CAD files).
    for f in s.folder.rglob("*"):
        if f.is_file() and f.name != SECRETS_JSON:
            assert PASSWORD.encode() not in f.read_bytes(), f
    assert masked(PASSWORD) == MASK and PASSWORD not in MASK and masked("") == "(none)"


def test_a_password_in_an_old_session_json_moves_out_on_load(empty_session):
    s = empty_session
    path = s.folder / "session.json"
    doc = json.loads(path.read_text())
    doc["link"].update(kind="abb", rws_password=PASSWORD)
    path.write_text(json.dumps(doc))
    back = Session.load(s.folder)
    assert back.link_settings.rws_password == PASSWORD
    assert any("rws_password was stored in clear" in n for n in back.load_notes)
    assert PASSWORD not in path.read_text()  # cleaned at once, not at the next edit
    assert PASSWORD in (s.folder / SECRETS_JSON).read_text()


def test_a_secrets_file_others_may_change_is_refused_one_they_may_read_is_closed(
        empty_session):
    s = empty_session
    _abb(s)
    secrets = s.folder / SECRETS_JSON
    os.chmod(secrets, 0o666)
    with pytest.raises(SessionFileError, match=r"other users may change it \(mode 0666\).*"
                       "chmod 600"):
        Session.load(s.folder)
    os.chmod(secrets, 0o644)
    back = Session.load(s.folder)
    assert _mode(secrets) == 0o600
    assert any("readable by other users (mode 0644)" in n for n in back.load_notes)


def test_every_file_is_fsynced_and_its_folder_after_the_rename(empty_session, monkeypatch):
    s = empty_session
    log: list[tuple[str, str]] = []
    fsync, replace = os.fsync, os.replace

    def logged_fsync(fd: int) -> None:
        log.append(("fsync", os.readlink(f"/proc/self/fd/{fd}")))
        fsync(fd)

    def logged_replace(a, b) -> None:  # noqa: ANN001
        replace(a, b)
        log.append(("replace", str(b)))

    monkeypatch.setattr(os, "fsync", logged_fsync)
    monkeypatch.setattr(os, "replace", logged_replace)
    _abb(s)
    folder = str(s.folder)
    at = log.index(("replace", f"{folder}/session.json"))
    assert log[at - 1][0] == "fsync" and ".session.json.tmp" in log[at - 1][1]
    assert log[at + 1] == ("fsync", folder)  # the rename itself is on disk
    at = log.index(("replace", f"{folder}/{SECRETS_JSON}"))
    assert log[at + 1] == ("fsync", folder)
    assert ("fsync", f"{folder}/cell") in log


def test_a_refused_save_keeps_the_change_and_says_not_saved_until_a_save_works(tmp_path):
    s = Session.from_sample("thesis_rv2aj", tmp_path / "s", with_mission=False)
    events: list = []
    s.bus.subscribe(events.append)
    blocker = s.folder / "session.json"
    blocker.unlink()
    blocker.mkdir()  # the rename onto it fails as a full or read-only disk would
    (blocker / "x").write_text("x")
    s.goto("teach.locations")
    s.teach("P1", pose_from_mm_deg([250, 0, 200, 0, 0, 180]))
    assert "P1" in s.locations  # kept in memory
    assert s.save_error
    failed = [e for e in events if isinstance(e, SaveStateChanged)]
    assert failed == [SaveStateChanged(False, s.save_error)]
    errors = [e.message for e in events if isinstance(e, ErrorRaised)]
    assert any(m.startswith("Not saved:") for m in errors)
    assert not any(str(s.folder) in m for m in errors)  # every page sees it: no path
    (blocker / "x").unlink()
    blocker.rmdir()
    s.teach("P2", pose_from_mm_deg([250, 50, 200, 0, 0, 180]))
    assert s.save_error == ""
    assert [e for e in events if isinstance(e, SaveStateChanged)][-1] == \
        SaveStateChanged(True, "")
    back = Session.load(s.folder)
    assert {"P1", "P2"} <= set(back.locations)
    s.close()
