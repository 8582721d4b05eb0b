"""Programs on the controller (ctl_device in C, through cffi): Upload Commit PROGRAM
checks and activates a program, Command PROGRAM_RUN runs it with the goals the host
predicts, the Program page reports it, and refusals carry their code."""

from __future__ import annotations

import zlib

import numpy as np
from ctl_support import CTL, CTL_ID, Device, lib_value, telemetry_reply
from test_ctl_bus import decode_sync_write

from snakebot.formats.gaittable import GaitTable
from snakebot.formats.program import (
    JointRecord,
    PeriodicSegment,
    Program,
    SerpenoidSegment,
    TableSegment,
)
from snakebot.formats.protocol import write
from snakebot.link.controller.limits import encode_limits
from snakebot.model.program_goals import predict

IDS = (11, 12, 13)
PERIOD = 20


def program() -> Program:
    joints = tuple(JointRecord(i, 512, 150, 874, k == 1) for k, i in enumerate(IDS))
    return Program(
        PERIOD,
        joints,
        (
            PeriodicSegment(0, 3000, 30),
            SerpenoidSegment(400, 3142, 1047, 0, 40),
            TableSegment(0, 3, 2),
        ),
        (((200, 150, 0), (-100, 0, 120), (0, 200, 200)),),
        ((520, 500, 480), (540, 510, 470), (530, 505, 475)),
    )


def commit_program(dev: Device, blob: bytes) -> int:
    """Upload blob, commit it as PROGRAM; returns Upload Result."""
    dev.upload(blob, commit=False)
    start = CTL.register("Upload Length").address
    what = lib_value("Upload Commit", "PROGRAM").to_bytes(1, "little")
    payload = len(blob).to_bytes(2, "little") + zlib.crc32(blob).to_bytes(4, "little") + what
    assert dev.one(write(CTL_ID, start, payload)).error == 0
    return dev.get("Upload Result")


def page(dev: Device, name: str) -> int:
    assert dev.set("Window Page", CTL.page("Program").number) == 0
    return dev.get(name)


def run(dev: Device, tick_ms: int, until_ms: int) -> list[tuple[int, dict[int, tuple[int, int]]]]:
    """(time, goals sent) for every control tick from 0 to until_ms."""
    seen = []
    for now in range(0, until_ms + 1, tick_ms):
        sent = dev.tick(now, {sid: telemetry_reply(sid) for sid in IDS})
        for packet in sent:
            if packet[4] == 0x83 and packet[5] == 30:  # SYNC_WRITE of Goal Position
                seen.append((now, decode_sync_write(packet)))
    return seen


def test_a_committed_program_runs_as_predicted_and_ends_done() -> None:
    dev = Device()
    prog = program()
    blob = prog.encode()
    assert commit_program(dev, blob) == lib_value("Upload Result", "OK")
    assert dev.get("Table Size") == len(blob)
    assert dev.get("Joint Count") == len(IDS)
    assert [r["ID"] for r in dev.servo_window()[:3]] == list(IDS)
    assert page(dev, "Program State") == lib_value("Program State", "IDLE")

    assert dev.command("PROGRAM_RUN") == 0
    assert dev.state == lib_value("State", "PLAYING")
    assert page(dev, "Program State") == lib_value("Program State", "RUNNING")
    expected = predict(prog)
    total = prog.total_steps
    # a control tick of 10 ms: two per program step
    seen = run(dev, 10, (total + 2) * PERIOD)
    assert len(seen) >= 2 * total
    for now, goals in seen:
        step = min(now // PERIOD, total - 1)
        got = np.array([goals[i][0] for i in IDS])
        assert np.abs(got - expected[step]).max() < 1.0, (now, got, expected[step])
    assert dev.state == lib_value("State", "IDLE")
    assert page(dev, "Program State") == lib_value("Program State", "DONE")
    assert page(dev, "Program Segment") == 2


def test_program_segment_follows_the_run() -> None:
    dev = Device()
    assert commit_program(dev, program().encode()) == 0
    assert dev.command("PROGRAM_RUN") == 0
    run(dev, 20, 35 * PERIOD)
    assert page(dev, "Program Segment") == 1
    assert dev.command("STOP") == 0
    assert page(dev, "Program State") == lib_value("Program State", "IDLE")


def test_out_of_range_program_is_refused_with_its_code_and_the_program_flag() -> None:
    dev = Device()
    joints = (JointRecord(11, 512, 400, 624),)
    wide = Program(PERIOD, joints, (SerpenoidSegment(1000, 1000, 0, 0, 10),))
    assert commit_program(dev, wide.encode()) == lib_value("Upload Result", "PROGRAM_OUT_OF_RANGE")
    assert dev.flags & lib_value("Error Flags", "PROGRAM")
    assert dev.get("Table Size") == 0  # nothing became active
    assert dev.command("PROGRAM_RUN") == 0
    assert dev.flags & lib_value("Error Flags", "REFUSED")
    assert page(dev, "Refusal Reason") == lib_value("Refusal Reason", "NO_TABLE")


def test_play_and_program_run_refuse_the_other_kind() -> None:
    dev = Device()
    assert commit_program(dev, program().encode()) == 0
    assert dev.command("PLAY") == 0
    assert page(dev, "Refusal Reason") == lib_value("Refusal Reason", "NO_TABLE")
    assert dev.state == lib_value("State", "IDLE")
    table = GaitTable(IDS, 20, True, ((200, 824),) * 3, np.array([[512, 512, 512]] * 2))
    assert dev.upload(table.encode()) == 0
    assert dev.command("PROGRAM_RUN") == 0
    assert page(dev, "Refusal Reason") == lib_value("Refusal Reason", "NO_TABLE")
    # a table committed as a program is refused for its magic
    assert commit_program(dev, table.encode()) == lib_value("Upload Result", "PROGRAM_BAD_MAGIC")


def test_a_program_beyond_the_robots_limits_is_refused_at_commit() -> None:
    dev = Device()
    narrow = encode_limits({i: (300, 700) for i in IDS})
    dev.upload(narrow, commit=False)
    start = CTL.register("Upload Length").address
    what = lib_value("Upload Commit", "LIMITS").to_bytes(1, "little")
    payload = len(narrow).to_bytes(2, "little") + zlib.crc32(narrow).to_bytes(4, "little") + what
    assert dev.one(write(CTL_ID, start, payload)).error == 0
    assert dev.get("Upload Result") == lib_value("Upload Result", "OK")
    # program() lets its joints range over 150..874: wider than the robot's
    outside = lib_value("Upload Result", "OUTSIDE_ROBOT_LIMITS")
    assert commit_program(dev, program().encode()) == outside
    assert dev.get("Table Size") == 0
