"""`snakebot bus scan` on lines that misbehave: damaged replies and echoes, silence, Ctrl-C."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import threading
import tty

import pytest
from click.testing import CliRunner

import snakebot.link.transport.ports  # noqa: F401  (registers sim://)
from snakebot.cli import main
from snakebot.facts import devices
from snakebot.formats import protocol, register_values
from snakebot.formats.protocol import ErrorFlags
from snakebot.link.bus import scan as bus_scan
from snakebot.link.transport import DxlClient, open_port, settings
from snakebot.link.transport.timing import wire_time_s
from snakebot.sim.options import SimOptions
from snakebot.sim.transports import PtyServer

pytestmark = pytest.mark.timeout(120)

SNAKE5_IDS = [10, 11, 15, 16]
NOISY = "sim://?robot=snake5&echo=1&corrupt=0.01&seed={seed}"


@pytest.mark.parametrize("seed", [0, 3])
def test_scan_through_a_noisy_one_wire_adapter_finds_every_servo(seed):
    with open_port(NOISY.format(seed=seed), 1_000_000, timeout=0) as link:
        found = bus_scan.scan(link, range(0, 254), [1_000_000])
        damaged = link.bus.faults.corrupted_bytes
    assert damaged > 0  # the line really did damage bytes during this scan
    assert [s.id for s in found] == SNAKE5_IDS
    assert all(s.model == "AX-12A" for s in found)


def test_scan_cli_keeps_going_past_damaged_replies():
    result = CliRunner().invoke(
        main, ["bus", "scan", "--port", NOISY.format(seed=0), "--ids", "0-20", "--json"]
    )
    assert result.exit_code == 0, result.output
    report = json.loads(result.stdout)
    assert [s["id"] for s in report["found"]] == SNAKE5_IDS
    assert report["interrupted"] is False


def test_scan_that_finds_nothing_fails_with_advice():
    result = CliRunner().invoke(main, ["bus", "scan", "--port", "sim://?ids=40", "--ids", "1-3"])
    assert result.exit_code == 1
    assert "error[E202]: no servo answered" in result.stderr and "--bauds all" in result.stderr


def test_bauds_all_covers_every_tabulated_ax_and_mx_rate():
    rates = register_values.parse_bauds("all")
    assert rates[0] == 1_000_000 and len(rates) == len(set(rates))
    assert set(register_values.COMMON_BAUDS) <= set(rates)
    mx = devices.load("MX-28").require_baud()
    assert {round(mx.rate(v)) for v in mx.fixed} <= set(rates)
    assert min(rates) == min(register_values.COMMON_BAUDS)


def test_scan_with_bauds_all_finds_a_servo_common_misses():
    port = "sim://?ids=3&baud=2000000"
    assert 2_000_000 not in register_values.COMMON_BAUDS
    args = ["bus", "scan", "--port", port, "--ids", "2-3", "--json", "--bauds"]
    assert CliRunner().invoke(main, [*args, "common"]).exit_code == 1
    result = CliRunner().invoke(main, [*args, "all"])
    assert result.exit_code == 0, result.output
    (servo,) = json.loads(result.stdout)["found"]
    assert (servo["id"], servo["model"], servo["baud"]) == (3, "AX-12A", 2_000_000)


def test_ctrl_c_prints_what_was_found_and_exits_130():
    # Every silent ID costs the scan its reply window in wall time (the latency allowance
    # and more), so after servo 2 the 252 silent IDs left keep it running for at least
    # 252 x 100 ms = 25 s: Ctrl-C lands mid-scan however late a busy machine delivers it,
    # and the test does not wait for any of that time.
    env = {**os.environ, "SNAKEBOT_LATENCY_MS": "100"}
    scan = subprocess.Popen(
        [sys.executable, "-m", "snakebot", "bus", "scan", "--port", "sim://?ids=1,2"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=env,
    )
    assert scan.stdout is not None
    lines = []
    for line in scan.stdout:  # the servos are printed as they are found
        lines.append(line)
        if line.split()[:1] == ["2"]:
            break
    scan.send_signal(signal.SIGINT)
    rest, err = scan.communicate(timeout=30)
    assert scan.returncode == 130, err
    assert "AX-12A" in "".join(lines)
    assert "Scan stopped by Ctrl-C" in err and "Traceback" not in err


@pytest.mark.parametrize("echo", [0, 1])
def test_a_reply_later_than_its_window_is_still_attributed_to_its_id(monkeypatch, echo):
    # The servo answers 1 ms after its Return Delay Time: past the silence window, so the
    # next ID's PING is already out (on a real bus: an adapter slower than its setting),
    # but after that PING, so the reply is intact. It names its ID; the scan takes it.
    monkeypatch.setenv(settings.ENV_LATENCY_MS, "0")
    monkeypatch.setenv(settings.ENV_MARGIN_MS, "0.5")
    url = f"sim://?ids=7&return_delay=500&delay=1&echo={echo}"
    with open_port(url, 1_000_000, timeout=0) as link:
        silence = bus_scan.silence_s(DxlClient(link, 1_000_000, echo=bool(echo)))
        reply_starts = wire_time_s(len(protocol.ping(7)), 1_000_000) + 500e-6 + 1e-3
        assert reply_starts > silence  # the reply really is late
        probes = list(bus_scan.scan_probes(link, range(5, 10), [1_000_000]))
    assert sorted(p.id for p in probes) == [5, 6, 7, 8, 9]  # one result per ID
    assert [(p.id, p.info.model) for p in probes if p.info] == [(7, "AX-12A")]


@pytest.mark.serial  # real time: the reply's lateness is counted in windows of the wall clock
def test_a_reply_windows_late_on_a_pty_still_finds_its_servo(monkeypatch):
    # A program answering on a pseudo-terminal delivers replies late when the machine is
    # busy (beside other work, `sim bus --pty`'s replies came tens of milliseconds late
    # and a --bauds all scan lost a servo in both passes). Here every reply comes 26 ms
    # late: two and a half windows, half a window (5 ms) from the PINGs before and after
    # it, while a later ID's PING is out. It names its ID, and no result for that ID has
    # been given: the scan must take it, however late. Eight IDs: five windows follow the
    # reply's (with four, one CI run beside other stages lost the reply, which the pty
    # had delivered later still, after the last window).
    monkeypatch.setenv(settings.ENV_LATENCY_MS, "0")
    monkeypatch.setenv(settings.ENV_MARGIN_MS, "10")
    monkeypatch.setenv(settings.ENV_ECHO, "off")
    delay_s = 26e-3
    query = f"ids=1&return_delay={bus_scan.longest_return_delay_us():g}&delay={delay_s * 1e3:g}"
    with (
        PtyServer(SimOptions.from_query(query).build_bus()) as server,
        open_port(server.device, 1_000_000, timeout=0) as link,
    ):
        silence = bus_scan.silence_s(DxlClient(link, 1_000_000, echo=False))
        reply = silence - bus_scan.scan_margin_s() + delay_s  # its first byte, after the PING
        assert 2 * silence < reply < 3 * silence  # two windows late: not the last ID's reply
        probes = list(bus_scan.scan_probes(link, range(0, 8), [1_000_000]))
    assert sorted(p.id for p in probes) == list(range(8))  # one result per ID
    assert [p.id for p in probes if p.info] == [1]


@pytest.mark.parametrize("before, rate", [(3_000_000, 2_000_000), (400_000, 500_000)])
def test_a_servo_that_heard_the_last_rate_as_garbage_answers_after_the_pause(
    monkeypatch, before, rate
):
    # PINGs at `before` reach a servo at `rate` as garbage that leaves it inside a frame
    # (without the pause between rates it swallows the first PINGs at its own rate and
    # ID 0 is missed); the pause, a frame reset and the host's margin, clears it.
    monkeypatch.setenv(settings.ENV_LATENCY_MS, "0")
    monkeypatch.setenv(settings.ENV_MARGIN_MS, "0.5")
    with open_port(f"sim://?ids=0&baud={rate}", before, timeout=0) as link:
        windows = sum(bus_scan.silence_s(DxlClient(link, b)) for b in (before, rate))
        start = link.bus.now
        found = bus_scan.scan(link, range(0, 30), [before, rate])
        took = link.bus.now - start
    assert [(s.id, s.baud) for s in found] == [(0, rate)]
    # the 30 silent windows at each rate (twice: silent IDs are PINGed again at the end),
    # the pause, the reply and the READ identifying it
    assert took < 2 * 30 * windows + protocol.FRAME_RESET_S + 5e-3


def test_a_reply_that_never_ends_is_garbled_not_an_error(monkeypatch):
    # On a real pty, a "reply" to ID 1 whose LEN announces more bytes than ever come:
    # the parser holds more than a status packet's worth, and the scan must still read
    # on (one byte at least), then try the ID again and call it garbled. The answering
    # thread may be late on a loaded machine: a wide margin keeps its reply in ID 1's window.
    monkeypatch.setenv(settings.ENV_LATENCY_MS, "0")
    monkeypatch.setenv(settings.ENV_MARGIN_MS, "100")
    monkeypatch.setenv(settings.ENV_ECHO, "off")
    master, slave = os.openpty()
    tty.setraw(slave)
    never_ends = bytes([0xFF, 0xFF, 1, 0xF0]) + bytes(8)

    def answer() -> None:
        heard = b""
        while True:
            try:
                heard += os.read(master, 64)
            except OSError:
                return
            while len(heard) >= 6:
                if heard[:6] == protocol.ping(1):
                    os.write(master, never_ends)
                heard = heard[6:]

    threading.Thread(target=answer, daemon=True).start()
    try:
        with open_port(os.ttyname(slave), 1_000_000, timeout=0) as link:
            probes = list(bus_scan.scan_probes(link, range(0, 3), [1_000_000]))
    finally:
        os.close(master)
        os.close(slave)
    assert sorted((p.id, p.info, p.garbled) for p in probes) == [
        (0, None, False),
        (1, None, True),
        (2, None, False),
    ]


def test_a_servo_whose_first_reply_is_lost_is_found_by_the_second_ping(monkeypatch):
    # One status packet in three is never sent: with seed 0, servo 1's reply to its
    # first PING is the one lost. Every ID silent after the sweep is PINGed once more
    # (and only those), so the scan still finds all four.
    monkeypatch.setenv(settings.ENV_ECHO, "off")
    pinged: list[int] = []
    listen = bus_scan._Sweep._listen

    def counted(self, servo_id):
        pinged.append(servo_id)
        return listen(self, servo_id)

    monkeypatch.setattr(bus_scan._Sweep, "_listen", counted)
    with open_port("sim://?ids=1,2,3,4&drop=0.3&seed=0", 1_000_000, timeout=0) as link:
        found = bus_scan.scan(link, range(0, 6), [1_000_000])
    assert sorted(s.id for s in found) == [1, 2, 3, 4]
    assert [pinged.count(i) for i in (0, 1, 5)] == [2, 2, 2]  # the silent ones, again
    assert pinged.index(5) < len(pinged) - 1 - pinged[::-1].index(1)  # 1 again at the end


def test_a_servo_found_on_the_retry_pass_is_listed_in_its_place():
    # the noisy-line scan found 16 before 15 once: 15's first PING lost, its retry at the end
    def servo(sid: int, baud: int) -> bus_scan.ServoInfo:
        return bus_scan.ServoInfo(sid, baud, 12, "AX-12A", 24, ErrorFlags(0))

    late = [servo(10, 57_600), servo(16, 1_000_000), servo(15, 1_000_000), servo(11, 1_000_000)]
    report = bus_scan.ScanReport("sim://", list(range(254)), [1_000_000, 57_600])
    for info in late:
        report.add(bus_scan.Probe(info.id, info.baud, info, False))
    ordered = [(s.baud, s.id) for s in report.found]
    assert ordered == [(1_000_000, 11), (1_000_000, 15), (1_000_000, 16), (57_600, 10)]
    assert bus_scan.in_scan_order(late, [1_000_000, 57_600]) == report.found
