"""MELFA wire formats: reply heads, positions, flags, program chunks, streaming lines."""

from __future__ import annotations

import numpy as np
import pytest

from assistant.emulators.melfa_program import MelfaProgram, ProgramSyntaxError
from assistant.links import melfa_protocol as mp
from assistant.links.arm_config import matches_melfa_flags
from assistant.links.errors import ProtocolError


def test_reply_heads_and_error_numbers():
    ok = mp.parse_reply("QoKJ1;10.00\r", "JPOSF")
    assert ok.accepted and not ok.controller_in_error and ok.body == "J1;10.00"
    in_error = mp.parse_reply("Qok\r", "JPOSF")
    assert in_error.accepted and in_error.controller_in_error
    refused = mp.parse_reply("QeR2600\r", "EXECMOV J9")
    assert not refused.accepted and refused.error_code == 2600
    exc = mp.refusal(refused, "EXECMOV J9", "Target outside the joint range")
    assert exc.code == "2600" and "QeR2600" in str(exc) and "joint range" in str(exc)
    assert mp.parse_reply("Qer1010;12;3\r", "RUN").error_code == 1010


@pytest.mark.parametrize("raw", ["HELLO\r", "\r", "QeRxyz\r", "#?%GARBLED\x15REPLY%?#\r"])
def test_garbage_is_a_protocol_error_quoting_the_reply(raw):
    with pytest.raises(ProtocolError) as info:
        mp.parse_reply(raw, "JPOSF")
    assert repr(raw) in str(info.value) and info.value.raw == raw


def test_request_format_and_parse():
    assert mp.format_request(1, 9, "EMDAT10 MOV P1") == b"1;9;EMDAT10 MOV P1\r"
    assert mp.parse_request(";;CNTLON") == (1, 1, "CNTLON")
    assert mp.parse_request("1;1;RUNPICK;1") == (1, 1, "RUNPICK;1")
    with pytest.raises(ValueError):
        mp.format_request(1, 1, "STOP\r1;1;SRVOFF")


def test_jposf_maps_wire_joints_to_the_five_axes(rv2aj):
    raw = "QoKJ1;10.90;J2;70.76;J3;64.16;J4;****;J5;40.06;J6;-183.40;;****,****;20;30.28;0\r"
    q = mp.parse_jposf(mp.parse_reply(raw, "JPOSF"), rv2aj.joint_names)
    assert np.allclose(np.degrees(q), [10.90, 70.76, 64.16, 40.06, -183.40])
    with pytest.raises(ProtocolError, match="J3"):
        mp.parse_jposf(mp.parse_reply("QoKJ1;1;J2;2\r", "JPOSF"), rv2aj.joint_names)
    with pytest.raises(ProtocolError, match="non-numeric"):
        mp.parse_jposf(mp.parse_reply("QoKJ1;abc;J2;2\r", "JPOSF"), rv2aj.joint_names)
    lit = mp.format_joint_literal(np.radians([1, 2, 3, 5, 6]), rv2aj.joint_names)
    assert lit == "(1.000,2.000,3.000,0.000,5.000,6.000)"  # J4 = 0 on the wire


def test_pose_literal_and_flags_pick_the_planned_branch(rv2aj, rng):
    for _ in range(20):
        q = rng.uniform(rv2aj.limits.lower, rv2aj.limits.upper)
        fl1, fl2 = mp.pose_flags(rv2aj, q)
        pose = mp.parse_pose_literal(mp.format_pose_literal(
            mp.MelfaPose(rv2aj.fk(q), fl1, fl2)))
        assert (pose.fl1, pose.fl2) == (fl1, fl2)
        assert np.allclose(pose.T_base_tool, rv2aj.fk(q), atol=5e-5)  # 0.001 deg, 1 um
        sols = rv2aj.ik(rv2aj.fk(q)).solutions
        matching = [s for s in sols if matches_melfa_flags(rv2aj, s, fl1, fl2)]
        assert len(matching) == 1 and np.allclose(matching[0], q, atol=1e-6)


def test_emdat_chunks_stay_below_the_command_buffer():
    lines = [f"{10 * i} MOV P{i}" for i in range(1, 200)]
    chunks = mp.emdat_chunks(lines)
    assert all(len(c) <= mp.EMDAT_MAX for c in chunks)
    assert "\v".join(chunks).split("\v") == lines
    prog = MelfaProgram("X")
    for c in chunks:
        for ln in c.split("\v"):
            prog.add_line(ln)
    assert prog.line_count == len(lines)
    with pytest.raises(ProgramSyntaxError):
        prog.add_line("2000 GOSUB *FOO")


def test_feedback_lines():
    seq, q = mp.parse_feedback_line("17,(10.000,20.000,30.000,0.000,40.000,50.000)\r",
                                    ["J1", "J2", "J3", "J5", "J6"])
    assert seq == 17 and np.allclose(np.degrees(q), [10, 20, 30, 40, 50])
    with pytest.raises(ProtocolError, match="GARBLED"):
        mp.parse_feedback_line("#?%GARBLED%?#", ["J1"])
