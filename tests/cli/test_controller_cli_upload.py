"""`snakebot upload` against the controller's real C device logic behind a pty: the
round trip, interrupted and damaged transfers, and the refusals that come before
anything is sent."""

from __future__ import annotations

import zlib

import pytest
from controller_cli_support import (
    FAST_ENV,
    SNAKE5_IDS,
    cli,
    cli_json,
    constant_table,
    crc_of,
    monitor_records,
    save,
    upload_packets,
    wave_table,
)

from snakebot.formats.gaittable import MAX_TABLE_BYTES, max_frames
from snakebot.formats.protocol import write
from snakebot.formats.upload_writes import chunk_limit, chunk_writes
from snakebot.link.controller import load
from snakebot.sim.controller_pty import (
    ControllerPty,
    CorruptOnce,
    CutAfter,
    is_commit,
    is_upload_chunk,
)

CTL = load()
CHUNK = chunk_limit(CTL, long_chunks=True)  # table bytes per chunk WRITE (the emulator has it)
_FIRST = chunk_writes(bytes(CHUNK), controller=CTL, long_chunks=True)[0]
CHUNK_SHARE = CHUNK / len(write(CTL.default_id, *_FIRST))  # table bytes per byte sent


@pytest.mark.parametrize("window", ["1", "8"])
def test_round_trip_controller_crc_equals_ours(controller, tmp_path, window):
    table = wave_table(frames=max_frames(4))  # the biggest table 4 joints allow
    path = save(table, tmp_path)
    result = cli(
        "upload", path, "--port", controller.device, env={"SNAKEBOT_UPLOAD_WINDOW": window}
    )
    assert result.exit_code == 0, result.output
    size = path.stat().st_size
    assert f"Uploaded {size} bytes in " in result.stdout
    # the test controller's pty is not paced, so no share of the wire is claimed
    assert "not a paced serial line" in result.stdout
    assert f"0x{crc_of(path):08x}" in result.stdout
    # the controller holds exactly the file's bytes (it cannot send a table back over the
    # link, so they are looked at in the device itself)
    assert controller.active_table() == path.read_bytes()
    chunks = [p for p in controller.host_packets if is_upload_chunk(p)]
    assert len(chunks) == -(-size // CHUNK)  # each sent once: nothing was lost


def test_json_report_carries_the_controllers_figures(controller, tmp_path):
    path = save(wave_table(), tmp_path)
    report = cli_json("upload", path, "--port", controller.device)
    assert report["crc"] == f"0x{crc_of(path):08x}"
    assert report["bytes"] == path.stat().st_size
    assert (report["joints"], report["frames"], report["period_ms"]) == (4, 200, 20)
    assert report["attempts"] == 1 and report["loop"] is True
    assert report["paced"] is False and "wire_percent" not in report  # an unpaced pty
    assert report["bytes_per_s"] > 0
    status = monitor_records(controller.device)[0]["controller"]
    assert status["table_crc"] == report["crc"] and status["table_bytes"] == report["bytes"]


def test_on_a_paced_link_the_report_gives_the_whole_uploads_share_of_the_wire(tmp_path):
    path = save(wave_table(), tmp_path)
    with ControllerPty(robot="snake5", baudrate=57600) as server:
        report = cli_json("upload", path, "--port", server.device)
    assert report["paced"] is True
    # the whole command (checks, chunks, commit, verification) against the wire's
    # 5760 bytes/s: at most the chunk stream's share of table bytes in what it sends
    assert report["wire_percent"] == pytest.approx(100 * report["bytes_per_s"] / 5760, abs=0.1)
    assert report["chunk_bytes"] == CHUNK
    assert 30 < report["wire_percent"] < 100 * CHUNK_SHARE


# 4: the last chunk of the 840-byte table (long chunks)
@pytest.mark.parametrize("k", [0, 1, 4])
def test_upload_cut_after_kth_chunk_leaves_old_table_playing(
    controller_with_table,
    old_table,
    tmp_path,
    k,
):
    server = controller_with_table
    new = save(constant_table(700), tmp_path)
    cut = CutAfter(lambda p: is_upload_chunk(p, CHUNK * k))
    with server.lock:
        server.line_filter = cut
    result = cli("upload", new, "--port", server.device, env=FAST_ENV)
    assert result.exit_code == 1
    assert result.stderr.splitlines()[-1].startswith("error[E301]: ")  # the link was cut
    assert "previous table" in result.stderr
    assert cut.cut and cut.dropped > 0
    with server.lock:
        server.line_filter = None  # the cable is back
    assert server.active_table() == old_table.encode()
    played = cli_json("play", "--port", server.device)
    assert played["state"] == "PLAYING"
    assert played["table"]["crc"] == f"0x{zlib.crc32(old_table.encode()):08x}"
    records = monitor_records(server.device, duration=0.3)
    goals = {s["goal"] for r in records[1:] for s in r["servos"]}
    assert goals == {300}  # the old table's value, not the new one's 700


def test_link_lost_right_after_the_commit_is_not_reported_as_success(
    controller_with_table,
    tmp_path,
):
    server = controller_with_table
    new = save(constant_table(700), tmp_path)
    with server.lock:
        server.line_filter = CutAfter(is_commit)
    result = cli("upload", new, "--port", server.device, env=FAST_ENV)
    assert result.exit_code == 1
    # the controller may have taken it: the message must not claim either way
    assert "unless the commit got through complete" in result.stderr
    assert server.active_table() == new.read_bytes()  # complete, never half


@pytest.mark.parametrize(
    "which",
    [lambda p: is_upload_chunk(p, 0), lambda p: is_upload_chunk(p, 2 * CHUNK), is_commit],
    ids=["first chunk", "third chunk", "commit"],
)
def test_a_damaged_packet_is_dropped_by_the_controller_and_sent_again(
    controller,
    tmp_path,
    which,
):
    path = save(wave_table(), tmp_path)
    damage = CorruptOnce(which)
    with controller.lock:
        controller.line_filter = damage
    result = cli("upload", path, "--port", controller.device)
    assert result.exit_code == 0, result.output
    assert damage.hit is not None
    assert "sending the table again (attempt 2 of 4)" in result.stderr
    assert "took 2 attempts" in result.stdout
    assert controller.active_table() == path.read_bytes()
    # the damaged packet went out again, intact
    original = controller.host_packets[damage.hit]
    assert controller.host_packets.count(original) == 2
    status = monitor_records(controller.device)[0]["controller"]
    assert status["pc_errors"] >= 1


def test_failure_reads_the_error_register_and_says_it_in_words(
    controller_with_table,
    tmp_path,
):
    server = controller_with_table
    new = save(wave_table(), tmp_path)
    # the third chunk is lost every time, the commit still arrives
    with server.lock:
        server.line_filter = lambda i, p: None if is_upload_chunk(p, 2 * CHUNK) else p
    result = cli("upload", new, "--port", server.device, env=FAST_ENV)
    assert result.exit_code == 1
    err = result.stderr
    assert "upload failed after 2 attempts" in err
    assert "got no acknowledgement" in err
    assert "UPLOAD_CRC (the last upload arrived damaged: its CRC-32 did not match)" in err
    assert "Check the USB cable" in err
    assert "The controller's previous table stays active" in err
    assert server.active_table() == constant_table(300).encode()


def test_oversized_table_is_refused_before_the_port_is_opened(controller, tmp_path):
    big = bytearray(constant_table(512, frames=max_frames(4)).encode())
    big[10:12] = (max_frames(4) + 1).to_bytes(2, "little")  # header claims one frame more
    path = tmp_path / "big.gait"
    path.write_bytes(bytes(big) + bytes(8))
    result = cli("upload", path, "--port", controller.device)
    assert result.exit_code == 2
    assert str(MAX_TABLE_BYTES) in result.stderr and "error: " in result.stderr
    assert controller.host_packets == []


def test_unknown_servos_are_refused_before_the_commit(
    controller_with_table,
    old_table,
    tmp_path,
):
    server = controller_with_table
    path = save(constant_table(512, ids=(1, 2, 3)), tmp_path)
    result = cli("upload", path, "--port", server.device)
    # the table does not fit the robot on the controller: bad input, as OUTSIDE_ROBOT_LIMITS
    assert result.exit_code == 2
    assert "IDs 1, 2, 3, which the controller does not have" in result.stderr
    assert "roster" in result.stderr and "10, 11, 15, 16" in result.stderr
    assert result.stderr.startswith("error: --new-servos: ")
    assert not [p for p in upload_packets(server) if is_commit(p)]
    assert server.active_table() == old_table.encode()
    # the user says the servos are really there
    result = cli("upload", path, "--port", server.device, "--new-servos")
    assert result.exit_code == 0, result.output
    assert "joined the roster" in result.stdout
    assert server.active_table() == path.read_bytes()


def test_a_controller_without_a_roster_takes_any_servos(controller, tmp_path):
    path = save(constant_table(512, ids=(1, 2, 3)), tmp_path)
    result = cli("upload", path, "--port", controller.device)
    assert result.exit_code == 0, result.output
    assert "knew no servos before (empty roster)" in result.stdout
    roster = [s["id"] for s in monitor_records(controller.device)[0]["servos"]]
    assert roster == [1, 2, 3]


def test_uploading_while_playing_says_the_gait_stopped(controller_with_table, tmp_path):
    server = controller_with_table
    assert cli_json("play", "--port", server.device)["state"] == "PLAYING"
    path = save(wave_table(ids=SNAKE5_IDS), tmp_path)
    result = cli("upload", path, "--port", server.device)
    assert result.exit_code == 0, result.output
    assert "stopped the gait that was running" in result.stdout
    assert monitor_records(server.device)[0]["controller"]["state"] == "IDLE"


def test_a_device_that_is_not_a_controller_is_named(tmp_path):
    path = save(wave_table(), tmp_path)
    # an AX-12 answering at ID 200 on an emulated servo bus served on a pty
    from snakebot.sim.options import SimOptions
    from snakebot.sim.transports import PtyServer

    server = PtyServer(SimOptions(ids=(200,)).build_bus()).start()
    try:
        result = cli("upload", path, "--port", server.device, "--baud", "1000000")
    finally:
        server.close()
    assert result.exit_code == 2
    assert "not a snakebot controller" in result.stderr


def test_progress_counts_only_acknowledged_bytes(controller):
    from snakebot.link.controller.client import ControllerClient
    from snakebot.link.controller.upload import upload_gait

    table = wave_table()
    size = table.size
    calls: list[tuple[int, int]] = []  # (attempt, bytes)
    attempt = [1]
    with controller.lock:
        controller.line_filter = CorruptOnce(lambda p: is_upload_chunk(p, 3 * CHUNK))
    with ControllerClient.open(controller.device, margin_s=0.2) as ctl:
        report = upload_gait(
            ctl,
            table,
            on_progress=lambda done, total: calls.append((attempt[0], done)),
            on_retry=lambda n, _total, _why: attempt.__setitem__(0, n),
        )
    assert report.attempts == 2
    first = [done for a, done in calls if a == 1]
    second = [done for a, done in calls if a == 2]
    assert first == sorted(first) and second == sorted(second)
    assert max(first) < size  # a chunk was lost: the bar never claimed the whole table
    assert second[-1] == size
