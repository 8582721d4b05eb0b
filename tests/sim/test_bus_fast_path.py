"""The bus's fast paths (a READ handed whole to a C servo, its status packet sent in
short on a quiet line) change nothing a master or a servo can observe.

A tapped bus (``Bus.tap``) takes the general path for every packet, so the same
instruction stream on a bus as built and on a tapped one must give the same bytes at
the same instants, the same servo states and the same counters: with echo, faults
(corruption, dropped and delayed replies, noise, a brownout), collisions (the master
talking over a reply), ID changes on the way, a servo on another baud rate, and a world
stepping on the bus clock.
"""

from __future__ import annotations

from hypothesis import example, given, settings
from hypothesis import strategies as st
from sim_support import hear

from snakebot import protocol as P
from snakebot.sim.bus import MASTER, Bus
from snakebot.sim.fast_servo import VirtualServo
from snakebot.sim.faults import Brownout, FaultConfig
from tests.sim.test_fast_servo import state

IDS = (1, 2, 3)
PRESENT = 36  # Present Position
ID_REG, BAUD_REG = 3, 4


def packets() -> st.SearchStrategy[bytes]:
    """What a master sends: mostly READs (the fast path), some damaged, some to nobody,
    goals, and now and then a write that moves a servo to another ID or baud rate."""
    read = st.builds(P.read, st.sampled_from((*IDS, 9)), st.integers(30, 46), st.integers(1, 8))
    damaged = read.map(lambda b: b[:-1] + bytes((b[-1] ^ 0x33,)))
    goals = st.dictionaries(
        st.sampled_from(IDS),
        st.integers(0, 1023).map(lambda v: v.to_bytes(2, "little")),
        min_size=1,
    ).map(lambda blocks: P.sync_write(30, 2, blocks))
    relink = st.one_of(
        st.builds(
            lambda i, new: P.write(i, ID_REG, bytes((new,))),
            st.sampled_from(IDS),
            st.sampled_from(IDS),
        ),
        st.builds(lambda i: P.write(i, BAUD_REG, bytes((3,))), st.sampled_from(IDS)),
    )
    return st.one_of(read, read, read, read, damaged, goals, relink)


def run(
    tapped: bool, config: dict, stream: list[tuple[float, bytes]]
) -> tuple[list[tuple[float, bytes]], list[tuple], tuple]:
    servos = [VirtualServo(i) for i in IDS]
    for s in servos:
        s.set_register("Return Delay Time", config["delay"])
    if config["other_baud"]:
        servos[2].set_register("Baud Rate", 3)
    bus = Bus(servos, echo=config["echo"], faults=config["faults"])
    if tapped:
        bus.tap()
    world: list[tuple[float, list[float]]] = []
    if config["world"]:
        bus.every(0.0013, lambda t: world.append((t, bus.positions())))
    heard = hear(bus, stream)
    stats = bus.stats
    counters = (
        stats.master_bytes_out,
        stats.master_bytes_in,
        stats.instructions,
        stats.replies,
        stats.collisions,
        bus.faults.corrupted_bytes,
        bus.faults.dropped_replies,
        bus.faults.noise_bursts,
    )
    return heard, [state(s) for s in servos], (counters, world)


faults = st.one_of(
    st.just(FaultConfig()),
    st.builds(
        FaultConfig,
        seed=st.integers(0, 5),
        corrupt=st.sampled_from((0.0, 0.01)),
        drop=st.sampled_from((0.0, 0.2)),
        delay_s=st.sampled_from((0.0, 0.0002)),
        jitter_s=st.sampled_from((0.0, 0.00005)),
        noise_rate=st.sampled_from((0.0, 200.0)),
        brownouts=st.sampled_from(((), (Brownout(2, 0.004, 0.003),))),
    ),
)


@settings(max_examples=120, deadline=None)
@given(
    config=st.fixed_dictionaries(
        {
            "delay": st.sampled_from((0, 5, 250)),
            "echo": st.booleans(),
            "other_baud": st.booleans(),
            "world": st.booleans(),
            "faults": faults,
        }
    ),
    # waits of 0 and a few microseconds make the master talk over replies
    stream=st.lists(
        st.tuples(st.sampled_from((0.0, 0.00003, 0.0002, 0.002, 0.02)), packets()), max_size=40
    ),
)
@example(  # a READ whose first header byte a collision damaged: the checksum can't tell
    config={
        "delay": 5,
        "echo": False,
        "other_baud": False,
        "world": False,
        "faults": FaultConfig(jitter_s=0.00005),
    },
    stream=[
        (0.0, P.read(1, 30, 1)),
        (0.0, P.write(2, BAUD_REG, bytes((3,)))),
        (0.0, P.read(1, 30, 1)),
        (0.0, P.read(1, 30, 1)),
        (0.002, P.write(1, BAUD_REG, bytes((3,)))),
    ],
)
def test_the_fast_paths_and_the_general_path_give_the_same_wire(config, stream):
    assert run(False, config, stream) == run(True, config, stream)


def test_the_fast_path_is_taken_for_a_plain_read():
    """The comparison above means something only if the fast path runs: on a quiet
    line a READ's status packet is the one that goes out in short (one transmission
    on the wire, heard by the master as sent)."""
    bus = Bus([VirtualServo(i) for i in IDS])
    bus.master_write(P.read(2, PRESENT, 2))
    assert bus.run_until_master_data(bus.now + 0.01, 8)
    (reply,) = bus._wire
    assert reply.source is bus.servo(2) and reply.unheard is not None
    assert bus._master_rx == [reply]
    out = bus.master_read(8)
    assert out == P.status(2, 0, out[5:7])


def test_a_read_right_after_a_sync_write_takes_the_fast_paths(monkeypatch):
    """A closed loop's tick: the goals in a SYNC_WRITE, then a READ while the SYNC_WRITE
    is still on the wire. The SYNC_WRITE reaches the C servos unparsed and the READ goes
    out in short behind it, its status packet too (that they do what the general path
    does is the comparison above, whose streams have such pairs)."""
    bus = Bus([VirtualServo(i) for i in IDS])
    transmitted, parsed = [], []
    transmit = bus._transmit
    monkeypatch.setattr(bus, "_transmit", lambda *a: transmitted.append(a[0]) or transmit(*a))
    parser_type = type(bus._listeners()[0].rx.parser)
    feed = parser_type.feed
    monkeypatch.setattr(
        parser_type, "feed", lambda self, data: parsed.append(bytes(data)) or feed(self, data)
    )
    bus.master_write(P.sync_write(30, 2, {i: (600 + i).to_bytes(2, "little") for i in IDS}))
    bus.master_write(P.read(2, PRESENT, 2))
    assert bus.run_until_master_data(bus.now + 0.01, 8)
    out = bus.master_read(8)
    assert out == P.status(2, 0, out[5:7])
    assert transmitted == [MASTER]  # the SYNC_WRITE alone went the general way
    assert parsed == []
    assert [bus.servo(i)._goal for i in IDS] == [601, 602, 603]
