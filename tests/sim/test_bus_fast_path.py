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

from snakebot.formats import protocol as P
from snakebot.formats.protocol.instructions import frame
from snakebot.link.transport import DxlClient
from snakebot.sim.bus.bus import Bus
from snakebot.sim.bus.faults import Brownout, FaultConfig
from snakebot.sim.servo.fast import VirtualServo
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
    # goals and speeds, a write elsewhere (the general path's), a block naming a servo
    # twice or one cut short, a damaged checksum, a goal out of range
    speeds = st.lists(
        st.tuples(st.sampled_from((*IDS, 9)), st.binary(min_size=4, max_size=4)), min_size=1
    ).map(lambda blocks: sync_write_frame(30, 4, b"".join(bytes((i,)) + d for i, d in blocks)))
    other = st.builds(
        lambda address, blocks: sync_write_frame(address, 1, blocks),
        st.sampled_from((24, 25, 32)),
        st.sampled_from((b"\x01\x01", b"\x02\x00\x03\x01", b"\x01\x01\x02")),
    )
    sync_damaged = goals.map(lambda b: b[:-1] + bytes((b[-1] ^ 0x5A,)))
    single = st.one_of(
        st.builds(P.ping, st.sampled_from((*IDS, 9))),
        st.builds(
            lambda i, v: P.write(i, 30, v.to_bytes(2, "little")),
            st.sampled_from(IDS),
            st.integers(0, 1100),
        ),
    )
    relink = st.one_of(
        st.builds(
            lambda i, new: P.write(i, ID_REG, bytes((new,))),
            st.sampled_from(IDS),
            st.sampled_from(IDS),
        ),
        st.builds(lambda i: P.write(i, BAUD_REG, bytes((3,))), st.sampled_from(IDS)),
    )
    # mostly READs and goals, as in a closed loop (one_of would draw each kind alike)
    kinds = (*(read,) * 8, damaged, goals, goals, speeds, other, sync_damaged, single, relink)
    return st.sampled_from(kinds).flatmap(lambda kind: kind)


def sync_write_frame(address: int, length: int, blocks: bytes) -> bytes:
    """A SYNC_WRITE frame of ``blocks`` as given (the builder refuses malformed ones)."""
    return frame(P.BROADCAST_ID, int(P.Instruction.SYNC_WRITE), bytes((address, length)) + blocks)


def receive(bus: Bus, stream: list[tuple[float, bytes]], size: int) -> list[tuple[float, bytes]]:
    """As a client's transactions hear ``stream``: before each packet the input is
    flushed, then reads of ``size`` bytes each (``Bus.master_receive``, a timed read of
    the sim:// port) until one by the packet's wait finds nothing; what each read got,
    and the bus time it returned at."""
    heard = []
    for wait, packet in stream:
        bus.master_flush_input()
        bus.master_write(packet)
        end = bus.now + wait
        while got := bus.master_receive(size, end):
            heard.append((bus.now, got))
    return heard


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
    size = config.get("read_size")
    heard = hear(bus, stream) if size is None else receive(bus, stream, size)
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


# waits of 0 and a few microseconds make the master talk over replies
streams = st.lists(
    st.tuples(st.sampled_from((0.0, 0.00003, 0.0002, 0.002, 0.02)), packets()),
    min_size=1,
    max_size=40,
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
            # None: byte by byte; else reads of this many bytes (8: a 2-byte READ's reply)
            "read_size": st.sampled_from((None, None, 1, 7, 8, 9, 64)),
        }
    ),
    stream=streams,
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


@settings(max_examples=80, deadline=None)
@given(
    config=st.fixed_dictionaries(
        {
            "delay": st.sampled_from((0, 5, 250)),
            "echo": st.just(False),
            "other_baud": st.just(False),
            "world": st.booleans(),
            "faults": st.just(FaultConfig()),
            "read_size": st.sampled_from((1, 7, 8, 8, 9, 64)),
        }
    ),
    stream=streams,
)
def test_on_a_quiet_line_a_client_hears_the_same(config, stream):
    """The line where the short ways are taken most (one baud rate, no echo, no
    faults), read as a client reads it: the same as above, where the general
    comparison rarely draws it."""
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
    is still on the wire, its reply read whole as the sim:// port reads it. Both frames
    go out in short, the SYNC_WRITE reaches the C servos in one call, unparsed, and the
    READ's reply is made and read without the general loop (that they do what the
    general path does is the comparison above, whose streams have such pairs)."""
    bus = Bus([VirtualServo(i) for i in IDS])
    general = []
    for name in ("_transmit", "_deliver", "run_until_master_data"):
        original = getattr(bus, name)
        monkeypatch.setattr(
            bus, name, lambda *a, name=name, f=original: general.append(name) or f(*a)
        )
    parser_type = type(bus._listeners()[0].rx.parser)
    feed = parser_type.feed
    monkeypatch.setattr(
        parser_type, "feed", lambda self, data: general.append("parse") or feed(self, data)
    )
    goals = P.sync_write(30, 2, {i: (600 + i).to_bytes(2, "little") for i in IDS})
    bus.master_write(goals)
    bus.master_write(P.read(2, PRESENT, 2))
    out = bus.master_receive(8, bus.now + 0.01)
    assert out == P.status(2, 0, out[5:7])
    # both frames, the servo's Return Delay Time, its reply: 10 bits a byte at 1 Mbps
    wire_s = (len(goals) + 8 + 8) * 10e-6 + bus.servo(2).return_delay_s
    assert abs(bus.now - wire_s) < 1e-12
    assert general == []
    assert bus._master_rx == [] and bus.master_in_waiting() == 0
    assert [bus.servo(i)._goal for i in IDS] == [601, 602, 603]


def closed_loop(tapped: bool) -> tuple:
    """snake5's closed loop through the client on sim://, as bench_sim.py runs it: per
    10 ms tick the goals in a SYNC_WRITE, then a READ of every servo's position."""
    with DxlClient("sim://?robot=snake5&return_delay=0", latency_s=0.0) as c:
        bus = c.port.bus
        if tapped:
            bus.tap()
        ids = [s.id for s in bus.servos]
        heard = []
        for k in range(30):
            c.sync_write(
                30, 2, {i: (400 + 7 * k + 40 * j).to_bytes(2, "little") for j, i in enumerate(ids)}
            )
            heard += [(c.read_u16(i, PRESENT), bus.now) for i in ids]
            bus.run_until((k + 1) / 100)
        stats = bus.stats
        return heard, [state(s) for s in bus.servos], (stats.master_bytes_in, stats.replies)


def test_the_closed_loop_through_the_client_is_the_same_on_a_tapped_bus():
    """End to end, the port and the client included: the short ways (the SYNC_WRITE in
    one C call, the READ held and answered whole) change no position heard, no instant
    and no servo state."""
    fast, general = closed_loop(False), closed_loop(True)
    assert fast == general
    assert len({position for position, _ in fast[0]}) > 4  # the servos did move
