"""Downloads: files with names, bytes and MIME types; a deterministic zip for several files."""

from __future__ import annotations

import io
import zipfile

import pytest

from assistant.export import DIALECT_NAMES, ExportError, export_files
from assistant.export.dialect import ProgramFile


@pytest.mark.parametrize("dialect", DIALECT_NAMES)
def test_export_files_gives_bytes_names_and_mime(robot_for, program_for, dialect):
    """The thesis program on an arm the dialect's controller runs (URScript: a UR5)."""
    robot = robot_for(dialect)
    res = export_files(program_for("thesis", robot), dialect, robot)
    assert res.dialect == dialect and res.primitives == 7
    names = [f.name for f in res.files]
    expected = {"melfa": ["THESIS.MB4", "THESIS.POS"], "krl": ["thesis.src", "thesis.dat"],
                "rapid": ["thesis.mod"], "urscript": ["thesis.script"],
                "fanuc": ["THESIS.LS"], "yaskawa": ["THESIS.JBI"]}[dialect]
    assert names == expected
    for f in res.files:
        assert f.mime.startswith("text/plain") and f.data.decode("ascii")
    if len(res.files) > 1:
        assert res.download is res.zip and res.zip.mime == "application/zip"
        with zipfile.ZipFile(io.BytesIO(res.zip.data)) as z:
            assert z.namelist() == names
            for f in res.files:
                assert z.read(f.name) == f.data
    else:
        assert res.zip is None and res.download is res.files[0]


def test_controller_files_use_crlf_and_scripts_lf(rv2aj, thesis_program, ur5, program_for):
    krl = export_files(thesis_program, "krl", rv2aj)
    assert b"\r\nDEF thesis( )\r\n" in krl.files[0].data
    ur = export_files(program_for("thesis", ur5), "urscript", ur5, check=False)
    assert b"\r\n" not in ur.files[0].data


def test_export_is_deterministic(rv2aj, thesis_program):
    a = export_files(thesis_program, "melfa", rv2aj)
    b = export_files(thesis_program, "melfa", rv2aj)
    assert a.zip.data == b.zip.data


def test_verification_catches_a_writer_that_lies(rv2aj, thesis_program, monkeypatch):
    from assistant.export import KrlDialect

    real = KrlDialect.write

    def shifted(self, program, robot):
        files = real(self, program, robot)
        dat = files[1]
        text = dat.text.replace("XP5={X 320.000", "XP5={X 320.100")
        return [files[0], ProgramFile(dat.name, text, dat.mime, dat.newline)]

    monkeypatch.setattr(KrlDialect, "write", shifted)
    with pytest.raises(ExportError, match="'P5' reads back 0.1000 mm"):
        export_files(thesis_program, "krl", rv2aj)


def test_unknown_dialect(rv2aj, thesis_program):
    with pytest.raises(ValueError, match="unknown dialect"):
        export_files(thesis_program, "gcode", rv2aj)
