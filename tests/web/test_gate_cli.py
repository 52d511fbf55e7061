"""`cellteach serve` off loopback: the address and two access codes printed once (operator,
viewer), the codes in no other line, a warning without TLS; a wrong or missing certificate and
an unsafe token file are one message and exit code 2."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest
from gate_helpers import client, run, sign_in

ROOT = Path(__file__).resolve().parents[2]


def _serve(tmp: Path, *extra: str) -> subprocess.Popen:
    return subprocess.Popen(
        [sys.executable, "-m", "assistant", "serve", "--cell", "thesis_rv2aj", "--empty",
         "--session", str(tmp / "session"), "--port", "0", *extra],
        cwd=ROOT, stderr=subprocess.PIPE, stdout=subprocess.DEVNULL, text=True)


def test_serve_off_loopback_prints_two_codes_and_keeps_them_out_of_other_lines(tmp_path):
    token_file = tmp_path / "tokens"
    proc = _serve(tmp_path, "--host", "0.0.0.0", "--token-file", str(token_file))
    lines: list[str] = []
    try:
        assert proc.stderr is not None
        for line in proc.stderr:
            lines.append(line)
            if "WARNING: the connection is not encrypted" in line:
                break
        text = "".join(lines)
        op = re.search(r"operator code \(can move the robot\): (\S+)", text)
        vw = re.search(r"viewer code \(watch only\): +(\S+)", text)
        where = re.search(r"open (http://\S+):(\d+)/ and enter an access code", text)
        assert op and vw and where, text
        operator, viewer = (ln.strip() for ln in token_file.read_text().splitlines()[1:3])
        assert (op.group(1), vw.group(1)) == (operator, viewer)
        others = [ln for ln in lines if " code (" not in ln]
        assert not any(operator in ln or viewer in ln for ln in others)
        url = f"http://127.0.0.1:{where.group(2)}"

        async def visit() -> tuple[int, int]:
            async with client() as c:
                async with c.get(url + "/", allow_redirects=False) as r:
                    denied = r.status
                return denied, (await sign_in(c, url, operator)).status

        assert run(visit()) == (401, 303)
    finally:
        proc.terminate()
        proc.wait(20)
    # The tokens never went to a log line either (the whole stderr after the links).
    rest = proc.stderr.read() if proc.stderr else ""
    assert operator not in rest and viewer not in rest


def _serve_fails(tmp: Path, *extra: str) -> str:
    proc = subprocess.run(
        [sys.executable, "-m", "assistant", "serve", "--empty", "--session",
         str(tmp / "session"), "--port", "0", "--host", "0.0.0.0", *extra],
        cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2, proc.stderr
    assert "Traceback" not in proc.stderr
    return proc.stderr


def test_a_wrong_certificate_is_one_message_and_exit_2(tmp_path):
    (tmp_path / "cert.pem").write_text("not a certificate\n")
    err = _serve_fails(tmp_path, "--certfile", str(tmp_path / "cert.pem"))
    assert "cert.pem" in err and "PEM certificate" in err


def _refused_in_process(tmp: Path, capsys, monkeypatch, *extra: str) -> str:
    """`cellteach serve` in this process (no interpreter to start): it must refuse before it
    serves anything - serving fails the test at once instead of running forever."""
    import web.app
    from assistant import cli

    def served(*a: object, **kw: object) -> None:
        raise AssertionError("cellteach served: the bad input was not refused")

    monkeypatch.setattr(web.app, "serve", served)
    code = cli.main(["serve", "--empty", "--session", str(tmp / "session"), "--port", "0",
                     "--host", "0.0.0.0", *extra])
    err = capsys.readouterr().err
    assert code == 2, err
    return err


@pytest.mark.parametrize("which", ["--certfile", "--keyfile"])
def test_a_missing_certificate_or_key_is_named(tmp_path, capsys, monkeypatch, which):
    from gate_helpers import self_signed_cert

    cert, _ = self_signed_cert(tmp_path)
    missing = tmp_path / "nowhere.pem"
    args = ["--certfile", str(missing)] if which == "--certfile" else \
        ["--certfile", str(cert), "--keyfile", str(missing)]
    err = _refused_in_process(tmp_path, capsys, monkeypatch, *args)
    what = "certificate (--certfile)" if which == "--certfile" else "private key (--keyfile)"
    assert f"cellteach: cannot read the {what} {missing}: no such file" in err
    assert "None" not in err


def test_an_unsafe_token_file_is_refused_with_what_to_do(tmp_path, capsys, monkeypatch):
    tokens = tmp_path / "tokens"
    tokens.write_text("operator-code-of-some-length\nviewer-code-of-some-length\n")
    tokens.chmod(0o666)
    err = _refused_in_process(tmp_path, capsys, monkeypatch, "--token-file", str(tokens))
    assert "can be read and changed by other users (mode 0666)" in err
    assert f"chmod 600 {tokens}" in err and "operator-code-of-some-length" not in err
