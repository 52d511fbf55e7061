"""`cellteach serve` off loopback: two links printed once (operator, viewer), the token in no
other line, a warning without TLS; a wrong certificate is one message and exit code 2."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

from gate_helpers import client, run

ROOT = Path(__file__).resolve().parents[2]


def _serve(tmp: Path, *extra: str) -> subprocess.Popen:
    return subprocess.Popen(
        [sys.executable, "-m", "assistant", "serve", "--cell", "thesis_rv2aj", "--empty",
         "--session", str(tmp / "session"), "--port", "0", *extra],
        cwd=ROOT, stderr=subprocess.PIPE, stdout=subprocess.DEVNULL, text=True)


def test_serve_off_loopback_prints_two_links_and_keeps_tokens_out_of_other_lines(tmp_path):
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
        op = re.search(r"operator link \(can move the robot\): (\S+)", text)
        vw = re.search(r"viewer link \(watch only\): +(\S+)", text)
        assert op and vw, text
        operator, viewer = (ln.strip() for ln in token_file.read_text().splitlines()[1:3])
        assert op.group(1).endswith(f"?token={operator}")
        assert vw.group(1).endswith(f"?token={viewer}")
        others = [ln for ln in lines if "link" not in ln]
        assert not any(operator in ln or viewer in ln for ln in others)
        port = int(re.search(r":(\d+)/\?token=", op.group(1)).group(1))

        async def visit() -> tuple[int, int]:
            async with client() as c:
                async with c.get(f"http://127.0.0.1:{port}/", allow_redirects=False) as r:
                    denied = r.status
                async with c.get(f"http://127.0.0.1:{port}/?token={operator}",
                                 allow_redirects=False) as r:
                    return denied, r.status

        assert run(visit()) == (401, 303)
    finally:
        proc.terminate()
        proc.wait(20)
    # The tokens never went to a log line either (the whole stderr after the links).
    rest = proc.stderr.read() if proc.stderr else ""
    assert operator not in rest and viewer not in rest


def test_a_wrong_certificate_is_one_message_and_exit_2(tmp_path):
    (tmp_path / "cert.pem").write_text("not a certificate\n")
    proc = subprocess.run(
        [sys.executable, "-m", "assistant", "serve", "--empty", "--session",
         str(tmp_path / "session"), "--port", "0", "--host", "0.0.0.0", "--certfile",
         str(tmp_path / "cert.pem")], cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2
    assert "cert.pem" in proc.stderr and "Traceback" not in proc.stderr
