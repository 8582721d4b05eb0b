"""The upload as one stream (checks, chunks, commit, verification) against the
controller's real C device logic behind a pty: the checks' READs go out with the first
chunks, a check that fails while chunks are in flight stops the upload before the commit,
an answer that did not come back is asked again before the commit, and the verification
READ right behind the commit reads what the commit made active."""

from __future__ import annotations

import zlib

import pytest
from controller_cli_support import constant_table, wave_table

from snakebot.core import lib
from snakebot.formats.protocol import Instruction, write
from snakebot.link.controller import load
from snakebot.link.controller.client import ControllerClient
from snakebot.link.controller.errors import ControllerError, UploadError
from snakebot.link.controller.upload import CAPACITY, HEAD_REGISTERS, VERIFY_REGISTERS, upload_gait
from snakebot.sim.controller_pty import CorruptOnce, is_commit, is_upload_chunk

CTL = load()
SELECTOR = CTL.register("Window Page")


def span(*names: str) -> tuple[int, int]:
    """(address, length) of the one READ that spans the registers ``names``."""
    regs = [CTL.register(n) for n in names]
    start = min(r.address for r in regs)
    return start, max(r.end for r in regs) - start


def is_read(packet: bytes, address: int, length: int | None = None) -> bool:
    return (
        packet[4] == Instruction.READ
        and packet[5] == address
        and (length is None or packet[6] == length)
    )


def is_page(packet: bytes, page: int) -> bool:
    return packet[4] == Instruction.WRITE and packet[5:-1] == bytes([SELECTOR.address, page])


CAPACITY_READ = span(CAPACITY)
CAPACITY_PAGE = CTL.page_number(CAPACITY)
ROSTER_READ = len(wave_table().joint_ids) * CTL.servo_record_size  # the old table's 4 joints


def open_client(server) -> ControllerClient:
    return ControllerClient.open(server.device, margin_s=0.2)


def test_one_stream_carries_the_checks_chunks_commit_and_verification(
    controller_with_table, old_table
):
    server = controller_with_table
    table = wave_table()
    with open_client(server) as ctl:
        report = upload_gait(ctl, table, window=8)
    assert report.attempts == 1 and server.active_table() == table.encode()
    sent = server.host_packets
    # the checks first: one READ from Model Number to Table CRC (identify and what the
    # controller holds), then Table Capacity on its page
    assert is_read(sent[0], *span(*HEAD_REGISTERS))
    assert is_page(sent[1], CTL.page_number(CAPACITY))
    assert is_read(sent[2], *CAPACITY_READ)
    # the roster (4 joints, on page 0), asked once the head said how long it is
    roster = [i for i, p in enumerate(sent) if is_page(p, 0)]
    assert len(roster) == 1
    records = len(old_table.joint_ids) * CTL.servo_record_size
    assert is_read(sent[roster[0] + 1], CTL.servo_window_address, records)
    # every chunk once, then the commit, then the verification READ, and nothing more
    chunks = [p for p in sent if is_upload_chunk(p)]
    assert len(chunks) == report.chunks
    assert is_commit(sent[-2]) and roster[0] < len(sent) - 2
    assert is_read(sent[-1], *span(*VERIFY_REGISTERS))
    assert len(sent) == 3 + 2 + report.chunks + 2  # no exchange of its own outside it
    assert report.sent_bytes == sum(len(p) for p in sent)
    # what the verification read is what the commit made active
    assert report.crc == zlib.crc32(table.encode()) and report.frames == table.frame_count
    assert report.previous_crc == zlib.crc32(old_table.encode())


def test_without_a_roster_no_roster_is_read(controller):
    table = wave_table()
    with open_client(controller) as ctl:
        report = upload_gait(ctl, table)
    assert report.roster_before == []
    assert not [p for p in controller.host_packets if is_page(p, 0)]
    assert len(controller.host_packets) == 3 + report.chunks + 2


def after_failing(server, ctl: ControllerClient, result_before: dict[str, int]) -> None:
    """What a check that failed mid-stream must leave: chunks went out, no commit, and a
    quiet link (what was in flight came back before the error was raised)."""
    assert [p for p in server.host_packets if is_upload_chunk(p)], "no chunk was in flight"
    assert not [p for p in server.host_packets if is_commit(p)]
    assert ctl.link.port.in_waiting == 0
    assert ctl.read("Upload Result") == result_before


# 10 frames: one chunk, so that without the hold the commit would go out at once, in
# the same window as the checks; 250 frames: 11 chunks
@pytest.mark.parametrize("frames", [10, 250])
def test_a_table_over_the_capacity_stops_while_chunks_are_in_flight(
    controller_with_table, old_table, frames
):
    server = controller_with_table
    table = wave_table(frames=frames)
    lib.ctl_set_capacity(server.device_logic.d, table.size - 1)
    with open_client(server) as ctl:
        result_before = ctl.read("Upload Result")
        server.host_packets.clear()
        with pytest.raises(ControllerError, match=f"holds at most {table.size - 1}") as caught:
            upload_gait(ctl, table, window=8)
        assert "nothing was committed" in str(caught.value)
        after_failing(server, ctl, result_before)
        assert server.active_table() == old_table.encode()
        # the same client goes on: the board takes the table once it has room
        lib.ctl_set_capacity(server.device_logic.d, table.size)
        assert upload_gait(ctl, table).attempts == 1
    assert server.active_table() == table.encode()


@pytest.mark.parametrize("frames", [10, 250])
def test_servos_outside_the_roster_stop_while_chunks_are_in_flight(
    controller_with_table, old_table, frames
):
    server = controller_with_table
    table = constant_table(512, ids=(1, 2, 3, 4), frames=frames)
    with open_client(server) as ctl:
        result_before = ctl.read("Upload Result")
        server.host_packets.clear()
        with pytest.raises(UploadError, match="IDs 1, 2, 3, 4, which the controller"):
            upload_gait(ctl, table, window=8)
        after_failing(server, ctl, result_before)
        assert server.active_table() == old_table.encode()
        report = upload_gait(ctl, table, allow_new_servos=True)
    assert report.new_servos == [1, 2, 3, 4] and server.active_table() == table.encode()


@pytest.mark.parametrize(
    "which",
    [
        lambda p: is_read(p, *span(*HEAD_REGISTERS)),
        lambda p: is_read(p, *CAPACITY_READ),
        lambda p: is_read(p, CTL.servo_window_address, ROSTER_READ),
        lambda p: is_page(p, CAPACITY_PAGE),
    ],
    ids=["head READ", "capacity READ", "roster READ", "capacity page WRITE"],
)
def test_a_check_without_an_answer_is_asked_again_before_the_commit(controller_with_table, which):
    server = controller_with_table
    damage = CorruptOnce(which)
    with server.lock:
        server.line_filter = damage
    table = wave_table()
    with open_client(server) as ctl:
        report = upload_gait(ctl, table, window=8)
    assert damage.hit is not None
    assert server.active_table() == table.encode()
    sent = server.host_packets
    again = [i for i, p in enumerate(sent) if i > damage.hit and p == sent[damage.hit]]
    commit = next(i for i, p in enumerate(sent) if is_commit(p))
    assert again and again[0] < commit  # asked again, and answered, before the commit
    assert report.attempts <= 2


def test_a_refused_capacity_page_is_reported_as_the_controller_refusing_it(controller):
    """A firmware without the Program page refuses Window Page 16: the stop-and-wait
    question after the stream names the refusal, and nothing is committed."""

    def no_program_page(_i: int, packet: bytes) -> bytes:
        if is_page(packet, CAPACITY_PAGE):
            return write(packet[2], SELECTOR.address, bytes([SELECTOR.value_range()[1]]))
        return packet

    with controller.lock:
        controller.line_filter = no_program_page
    with open_client(controller) as ctl:
        with pytest.raises(ControllerError, match="refused WRITE 126"):
            upload_gait(ctl, wave_table())
    assert not [p for p in controller.host_packets if is_commit(p)]
