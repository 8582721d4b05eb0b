"""A scan's wait for a missing reply scales with the baud rate: a silent ID costs the
PING, the longest Return Delay Time and a status packet's first byte (plus the adapter's
margin), not a whole reply timeout; a reply that has begun is still read whole, at any
rate, with or without a one-wire echo. On the emulated bus (sim://, whose clock the
reads drive) and on the paced pseudo-terminal, where the wall clock counts: there the
window ends before a status packet at the slowest rate is complete."""

from __future__ import annotations

import pytest

import snakebot.link.transport.ports  # noqa: F401  (registers sim://)
from snakebot.formats import protocol, register_values
from snakebot.link.bus import scan as bus_scan
from snakebot.link.transport import DxlClient, open_port, settings
from snakebot.link.transport.timing import wire_time_s
from snakebot.sim.options import SimOptions
from snakebot.sim.transports import PtyServer

pytestmark = pytest.mark.timeout(120)

SLOWEST = min(register_values.all_bauds())
LONGEST_DELAY_US = 508.0  # an AX-12's Return Delay Time 254


@pytest.fixture
def tight(monkeypatch):
    """No USB adapter and a small host margin: the silence window ends before a status
    packet at the slowest rate is complete, so a reply must extend it."""
    monkeypatch.setenv(settings.ENV_LATENCY_MS, "0")
    monkeypatch.setenv(settings.ENV_MARGIN_MS, "3")


def test_the_longest_return_delay_comes_from_the_descriptions(monkeypatch):
    assert bus_scan.longest_return_delay_us() == LONGEST_DELAY_US
    monkeypatch.setenv(settings.ENV_RETURN_DELAY_US, "900")  # told of a longer one
    assert bus_scan.longest_return_delay_us() == 900


@pytest.mark.usefixtures("tight")
def test_the_silence_window_ends_before_a_whole_status_would():
    for baud in register_values.all_bauds():
        with open_port("sim://?ids=1", baud, timeout=0) as link:
            client = DxlClient(link, baud, echo=False)
            silence = bus_scan.silence_s(client)
            ping_len = len(protocol.ping(1))
            # a reply's first byte can be due no later than this
            assert silence > wire_time_s(ping_len + 1, baud) + LONGEST_DELAY_US * 1e-6
            # ...and a missing one costs less than waiting out a whole status packet
            assert silence < client.timing.reply_timeout_s(ping_len, 0)


@pytest.mark.usefixtures("tight")
@pytest.mark.parametrize("echo", [0, 1])
def test_the_emulated_bus_at_the_slowest_rate_finds_a_servo_with_the_longest_delay(echo):
    url = f"sim://?ids=7&baud={SLOWEST}&return_delay={LONGEST_DELAY_US:g}&echo={echo}"
    with open_port(url, SLOWEST, timeout=0) as link:
        found = bus_scan.scan(link, range(5, 10), [SLOWEST])
    assert [(s.id, s.baud, s.model) for s in found] == [(7, SLOWEST, "AX-12A")]


@pytest.mark.usefixtures("tight")
def test_silent_ids_cost_the_silence_window_in_bus_time(monkeypatch):
    monkeypatch.setenv(settings.ENV_ECHO, "off")  # no echo probe before the scan
    ids = range(20, 40)
    with open_port(f"sim://?ids=1&baud={SLOWEST}", SLOWEST, timeout=0) as link:
        silence = bus_scan.silence_s(DxlClient(link, SLOWEST, echo=False))
        full = DxlClient(link, SLOWEST, echo=False).timing.reply_timeout_s(6, 0)
        start = link.bus.now
        assert bus_scan.scan(link, ids, [SLOWEST]) == []
        per_id = (link.bus.now - start) / len(ids) / 2  # each silent ID is PINGed twice
    assert wire_time_s(len(protocol.ping(1)), SLOWEST) < per_id <= silence < full


@pytest.mark.serial  # real time: the first byte must come within the margin
@pytest.mark.parametrize("echo", [False, True])
def test_the_paced_pty_at_the_slowest_rate_finds_a_servo_with_the_longest_delay(monkeypatch, echo):
    # The most margin that still ends the window before the status is complete (5 bytes
    # after its first), so a reply must extend it; the rest absorbs a loaded machine.
    monkeypatch.setenv(settings.ENV_LATENCY_MS, "0")
    monkeypatch.setenv(settings.ENV_MARGIN_MS, "4.5")
    with DxlClient("sim://?ids=3", SLOWEST) as client:
        silence = bus_scan.silence_s(client)
    assert silence < wire_time_s(12, SLOWEST) + LONGEST_DELAY_US * 1e-6
    query = f"ids=3&baud={SLOWEST}&return_delay={LONGEST_DELAY_US:g}&echo={int(echo)}"
    with (
        PtyServer(SimOptions.from_query(query).build_bus()) as server,
        open_port(server.device, SLOWEST, timeout=0) as link,
    ):
        found = bus_scan.scan(link, range(0, 6), [SLOWEST])
    assert [(s.id, s.baud) for s in found] == [(3, SLOWEST)]
