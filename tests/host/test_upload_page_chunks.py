"""`snakebot upload` sends long chunks (Upload Data and window page Upload Data 2 in one
WRITE) when the controller has the page, and Upload Data's chunks when it refuses the page
(an older firmware), against the controller's real C device logic behind a pty."""

from __future__ import annotations

from controller_cli_support import cli_json, controller, save, wave_table  # noqa: F401

from snakebot.controller import load
from snakebot.controller.upload import LONG_CHUNK_PAGE, chunk_limit
from snakebot.gaittable import max_frames
from snakebot.protocol import Instruction, write
from snakebot.sim.controller_pty import is_upload_chunk

CTL = load()
SELECTOR = CTL.register("Window Page")
PAGE = CTL.page(LONG_CHUNK_PAGE).number
UNKNOWN_PAGE = SELECTOR.value_range()[1]  # described by nobody: the device refuses it


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
    """An older firmware refuses Window Page 19 with RANGE: seen here by turning the
    uploader's question into one about a page nobody describes."""

    def older_firmware(_i: int, packet: bytes) -> bytes:
        asks = packet[4] == Instruction.WRITE and packet[5:-1] == bytes([SELECTOR.address, PAGE])
        return write(packet[2], SELECTOR.address, bytes([UNKNOWN_PAGE])) if asks else packet

    with controller.lock:
        controller.line_filter = older_firmware
    path = save(wave_table(frames=max_frames(4)), tmp_path)
    report = cli_json("upload", path, "--port", controller.device)
    window = chunk_limit(CTL)
    assert report["chunk_bytes"] == window and report["attempts"] == 1
    sizes = chunk_sizes(controller.host_packets)
    assert sum(sizes) == path.stat().st_size and max(sizes) == window
    assert controller.active_table() == path.read_bytes()
