"""`snakebot.link.controller.upload_stream.stream`: WRITEs and READs with several in flight,
against the controller's real C device logic behind a pty. Answers go to the packets
they answer even when one is lost, a check that raises stops the sending and leaves the
link quiet, a held packet stops the stream, and added packets keep a page's WRITE and
its READ together."""

from __future__ import annotations

import pytest

from snakebot.formats import protocol
from snakebot.formats.protocol import Packet
from snakebot.link.controller import load
from snakebot.link.controller.client import ControllerClient
from snakebot.link.controller.upload_stream import Ask, stream
from snakebot.sim.controller_pty import CorruptOnce

CTL = load()
ID = CTL.default_id
SELECTOR = CTL.register("Window Page")
CAPACITY = CTL.register("Table Capacity")


def page(number: int, **kwargs) -> Ask:
    return Ask(protocol.write(ID, SELECTOR.address, bytes([number])), **kwargs)


def read(address: int, length: int, **kwargs) -> Ask:
    return Ask(protocol.read(ID, address, length), length, **kwargs)


def recorder(into: list, name: str):
    def on_reply(reply: Packet) -> tuple[Ask, ...]:
        into.append((name, reply.params))
        return ()

    return on_reply


@pytest.fixture
def ctl(controller):
    with ControllerClient.open(controller.device, margin_s=0.2) as client:
        yield client


def test_answers_find_their_packets_past_a_lost_one(controller, ctl):
    heard: list = []
    asks = [
        read(0, 6, on_reply=recorder(heard, "head")),
        page(16, on_reply=recorder(heard, "page")),
        read(CAPACITY.address, CAPACITY.size, on_reply=recorder(heard, "capacity")),
        read(0, 2, on_reply=recorder(heard, "model")),
    ]
    with controller.lock:  # the page WRITE is damaged: the controller drops it
        controller.line_filter = CorruptOnce(lambda p: p == asks[1].packet)
    result = stream(ctl.link, ID, asks, window=8)
    assert [name for name, _ in heard] == ["head", "capacity", "model"]
    assert heard[0][1] == ctl.read_block(0, 6)
    assert int.from_bytes(heard[2][1], "little") == CTL.model_number
    assert (result.sent, result.acked, result.lost) == (4, 3, 1)
    assert not result.complete and not result.error


def test_a_check_that_raises_stops_the_sending_and_leaves_the_link_quiet(controller, ctl):
    def refuse(_reply: Packet) -> tuple[Ask, ...]:
        raise RuntimeError("no")

    pings = [Ask(protocol.ping(ID)) for _ in range(20)]
    with pytest.raises(RuntimeError, match="no"):
        stream(ctl.link, ID, [read(0, 6, on_reply=refuse), *pings], window=4)
    # only what the window let out before the answer: the READ and three PINGs
    assert len(controller.host_packets) == 4
    assert ctl.link.port.in_waiting == 0  # their answers were taken in before the raise
    assert ctl.read("Model Number") == {"Model Number": CTL.model_number}


def test_a_packet_never_ready_holds_the_rest(controller, ctl):
    ready = [False]
    asks = [read(0, 6), Ask(protocol.ping(ID), ready=lambda: ready[0]), read(0, 2)]
    result = stream(ctl.link, ID, asks, window=8)
    assert result.held and result.sent == 1 and not result.complete
    assert controller.host_packets == [asks[0].packet]


def test_a_packet_goes_once_an_earlier_answer_makes_it_ready(controller, ctl):
    ready: list[bool] = []

    def opens(_reply: Packet) -> tuple[Ask, ...]:
        ready.append(True)
        return ()

    asks = [read(0, 6, on_reply=opens), Ask(protocol.ping(ID), ready=lambda: bool(ready))]
    result = stream(ctl.link, ID, [*asks, read(0, 2)], window=8)
    assert result.complete and result.sent == 3


def test_added_packets_go_after_a_read_that_follows_its_page(controller, ctl):
    added = [page(0), read(CTL.servo_window_address, 21, follows=True)]
    first = read(0, 6, on_reply=lambda _r: added)
    shown = page(16)
    capacity = read(CAPACITY.address, CAPACITY.size, follows=True)
    last = read(0, 2)
    # window 2: the head's answer comes while the capacity READ still waits to be sent
    result = stream(ctl.link, ID, [first, shown, capacity, last], window=2)
    assert result.complete and result.total == 6
    order = [first, shown, capacity, *added, last]
    assert controller.host_packets == [a.packet for a in order]
