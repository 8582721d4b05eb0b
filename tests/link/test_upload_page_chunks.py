"""`snakebot upload` sends long chunks (Upload Data and window page Upload Data 2 in one
WRITE) when the controller has the page, and Upload Data's chunks when it refuses the page
(an older firmware), against the controller's real C device logic behind a pty."""

from __future__ import annotations

from controller_cli_support import cli_json, controller, save, wave_table  # noqa: F401

from snakebot.formats.gaittable import max_frames
from snakebot.formats.protocol import write
from snakebot.formats.upload_writes import chunk_limit
from snakebot.link.controller import load
from snakebot.sim.controller_pty import is_upload_chunk

CTL = load()
OFFSET = CTL.register("Upload Offset")
SELECTOR = CTL.register("Window Page")
UNKNOWN_PAGE = SELECTOR.value_range()[1]  # described by nobody: the device refuses it


def as_without_page(_index: int, packet: bytes) -> bytes:
    """``packet`` as a firmware without page Upload Data 2 hears it: a long chunk's
    Window Page byte names a page nobody describes, refused with RANGE as such a firmware
    refuses the page. Other packets pass as they are."""
    data = bytearray(packet[6:-1])  # FF FF ID LEN INSTRUCTION address data... checksum
    at = SELECTOR.address - OFFSET.address
    if not is_upload_chunk(packet) or len(data) <= at:
        return packet
    data[at] = UNKNOWN_PAGE
    return write(packet[2], OFFSET.address, bytes(data))


def chunk_sizes(packets: list[bytes]) -> list[int]:
    """Table bytes of each upload chunk WRITE (its parameters less the address, the offset
    and, for a long chunk, the Window Page byte)."""
    window = CTL.register("Upload Data").size
    sizes = []
    for p in packets:
        if is_upload_chunk(p):
            n = p[3] - 2 - 1 - CTL.register("Upload Offset").size
            sizes.append(n - 1 if n > window else n)
    return sizes


def test_the_largest_table_goes_in_long_chunks(controller, tmp_path):  # noqa: F811
    path = save(wave_table(frames=max_frames(4)), tmp_path)
    size = path.stat().st_size
    report = cli_json("upload", path, "--port", controller.device)
    long = chunk_limit(CTL, long_chunks=True)
    assert report["chunk_bytes"] == long
    sizes = chunk_sizes(controller.host_packets)
    assert sum(sizes) == size and max(sizes) == long and len(sizes) == -(-size // long)
    assert controller.active_table() == path.read_bytes()


def test_a_controller_without_the_page_gets_upload_datas_chunks(controller, tmp_path):  # noqa: F811
    """An older firmware refuses Window Page 19 with RANGE, and with it the first long
    chunk (nothing of it is staged): seen here by turning each long chunk's page into one
    nobody describes. The upload goes on in Upload Data's chunks, in the same attempt."""
    with controller.lock:
        controller.line_filter = as_without_page
    path = save(wave_table(frames=max_frames(4)), tmp_path)
    report = cli_json("upload", path, "--port", controller.device)
    window = chunk_limit(CTL)
    assert report["chunk_bytes"] == window and report["attempts"] == 1
    chunks = [p for p in controller.host_packets if is_upload_chunk(p)]
    long = [p for p in chunks if chunk_sizes([p])[0] > window]
    assert long and chunks[: len(long)] == long  # the long ones came first, then no more
    sizes = chunk_sizes(chunks[len(long) :])
    assert sum(sizes) == path.stat().st_size and max(sizes) == window
    assert controller.active_table() == path.read_bytes()
