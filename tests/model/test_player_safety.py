"""Safe-state transitions, through the whole controller core: servo errors, bus loss and
PC-link loss stop the gait (torque off or hold, as configured); CLEAR brings it back."""

from __future__ import annotations

import numpy as np
import pytest
from ctl_support import CTL_ID, Device, telemetry_reply

from snakebot.formats.gaittable import GaitTable
from snakebot.formats.protocol import BROADCAST_ID, ErrorFlags, Instruction, PacketParser, ping
from snakebot.link.controller import ControllerErrors, SafeAction, State

IDS = (11, 12, 13)
TORQUE_OFF = bytes([0xFF, 0xFF, BROADCAST_ID, 4, Instruction.WRITE, 24, 0])


def torque_off_packet() -> bytes:
    body = TORQUE_OFF[2:]
    return TORQUE_OFF + bytes([~sum(body) & 0xFF])


def healthy(overrides: dict[int, bytes] | None = None) -> dict[int, bytes]:
    replies = {sid: telemetry_reply(sid) for sid in IDS}
    replies.update(overrides or {})
    return replies


@pytest.fixture
def dev() -> Device:
    d = Device()
    frames = np.array([[512, 512, 512], [600, 450, 300], [700, 400, 250]])
    t = GaitTable(IDS, 20, True, ((200, 824),) * 3, frames)
    assert d.upload(t.encode()) == 0
    assert d.command("PLAY") == 0 and d.state == State.PLAYING
    return d


def instructions(packets: list[bytes]) -> list[int]:
    return [PacketParser().feed(p)[0].code for p in packets]


def run(dev: Device, start: int, ticks: int, replies: dict[int, bytes]) -> list[bytes]:
    sent = []
    for k in range(ticks):
        sent += dev.tick(start + 10 * k, replies)
    return sent


def test_healthy_servos_keep_it_playing(dev):
    sent = run(dev, 0, 30, healthy())
    assert dev.state == State.PLAYING and dev.flags == 0
    assert Instruction.SYNC_WRITE in instructions(sent)


@pytest.mark.parametrize("error", [ErrorFlags.OVERLOAD, ErrorFlags.OVERHEATING])
def test_overload_or_overheating_stops_with_torque_off(dev, error):
    run(dev, 0, 3, healthy())
    sent = run(dev, 30, 4, healthy({12: telemetry_reply(12, error=error)}))
    assert dev.state == State.SAFE
    assert dev.flags & ControllerErrors.SERVO_ERROR
    # the tick after servo 12's reply: torque off first, and no more goals
    assert sent.count(torque_off_packet()) == 1
    after = sent[sent.index(torque_off_packet()) + 1 :]
    assert after and set(instructions(after)) == {Instruction.READ}
    later = run(dev, 70, 5, healthy())
    assert Instruction.SYNC_WRITE not in instructions(later)
    assert torque_off_packet() not in later  # torque off is sent once
    window = dev.servo_window(0)
    # the error byte mirrors the last reply (healthy again); the count remembers
    assert window[1]["Servo Error"] == 0 and window[1]["Error Count"] == 1


def test_hold_instead_of_torque_off(dev):
    assert dev.set("Safe Action", SafeAction.HOLD) == 0
    run(dev, 0, 3, healthy({11: telemetry_reply(11, error=ErrorFlags.OVERLOAD)}))
    sent = dev.tick(30, healthy())
    assert dev.state == State.SAFE and torque_off_packet() not in sent


def test_errors_outside_the_mask_do_not_stop_it(dev):
    run(dev, 0, 6, healthy({11: telemetry_reply(11, error=ErrorFlags.ANGLE_LIMIT)}))
    assert dev.state == State.PLAYING
    assert dev.set("Servo Error Mask", 0) == 0
    run(dev, 60, 6, healthy({11: telemetry_reply(11, error=ErrorFlags.OVERLOAD)}))
    assert dev.state == State.PLAYING


def test_bus_loss_after_the_limit_of_missed_reads(dev):
    limit = dev.get("Bus Loss Limit")
    silent = healthy()
    del silent[13]
    # servo 13 is read every third tick: limit - 1 misses are tolerated
    run(dev, 0, 3 * (limit - 1), silent)
    assert dev.state == State.PLAYING
    run(dev, 300, 4, silent)
    assert dev.state == State.SAFE and dev.flags & ControllerErrors.BUS_LOSS
    assert dev.servo_window(0)[2]["Timeout Count"] == limit
    assert dev.get("Bus Timeouts") == limit


def test_one_good_reply_resets_the_run_of_misses(dev):
    silent = healthy()
    del silent[13]
    for block in range(4):
        run(dev, 1000 * block, 9, silent)  # 3 misses of servo 13
        run(dev, 1000 * block + 500, 3, healthy())  # then it answers
    assert dev.state == State.PLAYING


def test_link_loss_only_when_configured(dev):
    run(dev, 0, 100, healthy())  # 1 s without PC traffic: fine by default
    assert dev.state == State.PLAYING
    assert dev.set("Link Timeout", 3) == 0  # 300 ms
    dev.now = 1000
    dev.one(ping(CTL_ID))
    for k in range(10):  # PC pings every 200 ms keep it alive
        run(dev, 1000 + 200 * k, 1, healthy())
        dev.now = 1000 + 200 * k
        dev.one(ping(CTL_ID))
    assert dev.state == State.PLAYING
    run(dev, 3000, 40, healthy())  # then 400 ms of silence
    assert dev.state == State.SAFE and dev.flags & ControllerErrors.LINK_LOSS


def test_clear_returns_to_idle_and_play_resumes(dev):
    run(dev, 0, 3, healthy({11: telemetry_reply(11, error=ErrorFlags.OVERLOAD)}))
    dev.tick(30, healthy())
    assert dev.state == State.SAFE
    assert dev.command("PLAY") == 0  # refused while safe
    assert dev.state == State.SAFE and dev.flags & ControllerErrors.REFUSED
    assert dev.command("CLEAR") == 0
    assert dev.state == State.IDLE and dev.flags == 0
    assert dev.command("PLAY") == 0 and dev.state == State.PLAYING
    sent = dev.tick(40, healthy())
    # torque comes back on (SYNC_WRITE to address 24) before the goals
    first = PacketParser().feed(sent[0])[0]
    assert first.code == Instruction.SYNC_WRITE and first.params[:2] == bytes([24, 1])
    run(dev, 50, 10, healthy())
    assert dev.state == State.PLAYING


def test_idle_controller_with_a_dead_servo_goes_safe_too(dev):
    assert dev.command("STOP") == 0 and dev.state == State.IDLE
    silent = healthy()
    del silent[11]
    run(dev, 0, 3 * dev.get("Bus Loss Limit"), silent)
    assert dev.state == State.SAFE
