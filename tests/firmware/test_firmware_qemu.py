"""The qemu board image under qemu-system-arm: it boots through the stub into the
relocated application, answers PING at ID 200 on the PC link (USART3), keeps answering
through garbage, and the runner always leaves no QEMU behind."""

from __future__ import annotations

import os
import random
import re
import socket
import time

import pytest
from firmware_support import (
    APP_BASE,
    CONTROLLER_ID,
    QEMU_DIR,
    STUB_BASE,
    build_firmware,
    client,
    symbols,
)

from snakebot.formats.protocol import DxlTimeout, Packet, PacketParser, encode_packet, ping, status
from snakebot.link.controller import load as load_controller
from snakebot.sim.qemu import Endpoint, QemuError, QemuFirmware

pytestmark = pytest.mark.qemu

VTOR = 0xE000ED08
GAP_S = 0.15  # longer than the firmware's 100 ms inter-byte gap (PCLINK_GAP_MS)


@pytest.fixture(scope="module")
def firmware_image():
    build_firmware()
    return QEMU_DIR / "flash.bin"


@pytest.fixture(scope="module")
def qemu(request, firmware_image):
    """One QEMU for the module, PC link on a pseudo-terminal; always stopped."""
    fw = QemuFirmware(firmware_image)
    request.addfinalizer(fw.stop)
    fw.start()
    return fw


@pytest.fixture
def link(qemu):
    with client(qemu.ports.pc_link) as c:
        yield c


def wait_for_answer(c, deadline_s: float = 10.0) -> Packet:
    """Ping until the first answer (the image may still be booting)."""
    end = time.monotonic() + deadline_s
    while True:
        try:
            return c.ping(CONTROLLER_ID, retries=0)
        except DxlTimeout:
            if time.monotonic() > end:
                raise


def registers(fw: QemuFirmware) -> dict[str, int]:
    text = fw.monitor("info registers")
    return {k: int(v, 16) for k, v in re.findall(r"\b(R\d\d)=([0-9a-f]{8})", text)}


def test_boots_and_answers_ping_at_200(link):
    reply = wait_for_answer(link)
    assert reply == Packet(CONTROLLER_ID, 0, b"")
    # and again, on the first try each time
    for _ in range(5):
        assert link.ping(CONTROLLER_ID, retries=0) == Packet(CONTROLLER_ID, 0, b"")


def test_the_pc_link_reaches_the_controllers_control_table(link):
    wait_for_answer(link)
    ctl = load_controller()
    model = ctl.register("Model Number")
    assert link.read_u16(CONTROLLER_ID, model.address) == model.default  # 0x5342
    assert link.read_u8(CONTROLLER_ID, ctl.register("ID").address) == CONTROLLER_ID


def read_for(port, seconds: float) -> bytes:
    """Everything the port delivers within `seconds`."""
    got = b""
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        got += port.read(256)
        time.sleep(0.01)
    return got


def test_reply_bytes_are_exactly_a_status_packet(qemu, link):
    wait_for_answer(link)
    port = link.port
    port.reset_input_buffer()
    port.write(ping(CONTROLLER_ID))
    assert read_for(port, 0.5) == status(CONTROLLER_ID)  # one status packet, nothing else


def test_other_ids_and_broadcast_get_no_answer(link):
    wait_for_answer(link)
    with pytest.raises(DxlTimeout):
        link.ping(1, retries=0)
    port = link.port
    port.reset_input_buffer()
    port.write(ping(0xFE))  # broadcast: a device never answers it
    assert read_for(port, 0.3) == b""


def test_running_image_is_the_relocated_application(qemu, link):
    wait_for_answer(link)
    elf_syms = symbols(QEMU_DIR / "firmware.elf")
    assert elf_syms["hal_vector_table"] == APP_BASE
    assert qemu.read_word(VTOR) == APP_BASE
    # what is in flash at both addresses is what was built: the stub's and the
    # application's initial stack pointer and reset vector
    stub = (QEMU_DIR / "stub.bin").read_bytes()
    app = (QEMU_DIR / "firmware.bin").read_bytes()
    for base, image in ((STUB_BASE, stub), (APP_BASE, app)):
        assert qemu.read_word(base) == int.from_bytes(image[0:4], "little")
        assert qemu.read_word(base + 4) == int.from_bytes(image[4:8], "little")
    regs = registers(qemu)
    assert APP_BASE <= regs["R15"] < APP_BASE + len(app)  # executing the application
    assert 0x20000000 < regs["R13"] <= 0x20002000  # on its stack, in the 8 KB of RAM


def test_stub_waits_when_no_application_is_present(tmp_path, firmware_image):
    blank = tmp_path / "stub-only.bin"
    stub = (QEMU_DIR / "stub.bin").read_bytes()
    blank.write_bytes(stub + b"\xff" * (APP_BASE - STUB_BASE - len(stub) + 4096))
    with QemuFirmware(blank) as fw:
        time.sleep(0.2)
        regs = registers(fw)
        assert STUB_BASE <= regs["R15"] < STUB_BASE + len(stub)
        assert fw.read_word(VTOR) == 0  # never handed over


def _garbage(seed: int, n: int) -> bytes:
    rng = random.Random(seed)
    # no byte 200, so no garbage packet can be addressed to the controller by chance
    return bytes(b if b != CONTROLLER_ID else 0 for b in rng.randbytes(n))


NASTY = [
    bytes([0xFF] * 40),  # a long run of header bytes
    bytes.fromhex("ff ff c8 02 01 00"),  # PING to 200 with a wrong checksum
    bytes.fromhex("ff ff c8 00 ff ff 01 01"),  # impossible lengths
    bytes.fromhex("ff ff c8 f6 03"),  # a header promising 246 bytes, then silence
    bytes.fromhex("ff ff c8 02"),  # a truncated packet
    encode_packet(CONTROLLER_ID, 0x01, b"")[:-1] + b"\x00",  # corrupted checksum
]


def answers_again(c) -> None:
    """After garbage: the controller answers again (once it has worked through the
    garbage and seen a 100 ms pause), and from then on at the first try."""
    wait_for_answer(c)
    for _ in range(3):
        assert c.ping(CONTROLLER_ID, retries=0) == Packet(CONTROLLER_ID, 0, b"")


@pytest.mark.serial  # its deadline counts on QEMU keeping pace: nothing beside it
@pytest.mark.parametrize("junk", NASTY, ids=lambda b: b.hex()[:16])
def test_keeps_answering_after_malformed_input(link, junk):
    """A stalled packet start (say, a header promising 246 bytes) would swallow the next
    PINGs for good without the device's inter-byte timeout; the deadline in
    wait_for_answer leaves time for fewer PINGs than it would take to fill 246 bytes."""
    wait_for_answer(link)
    link.port.write(junk)
    time.sleep(GAP_S)  # a device drops a packet that stalls for 100 ms
    answers_again(link)


def test_resynchronises_within_the_stream(link):
    """Garbage directly followed by a PING, no pause: the resynchronisation rule must
    find the PING behind bad checksums, bad lengths and stray header bytes."""
    wait_for_answer(link)
    junk = bytes.fromhex("00 ff 13 ff ff c8 02 01 00 ff ff ff 07 00 ff ff c8 01 ff")
    port = link.port
    port.reset_input_buffer()
    port.write(junk + ping(CONTROLLER_ID))
    parser = PacketParser()
    got = [p for p in parser.feed(read_for(port, 0.5)) if isinstance(p, Packet)]
    assert got == [Packet(CONTROLLER_ID, 0, b"")]


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_keeps_answering_after_a_flood_of_random_bytes(link, seed):
    wait_for_answer(link)
    port = link.port
    port.write(_garbage(seed, 4096))  # sixteen times the receive ring
    answers_again(link)
    # Whatever else comes back can only be late answers to PINGs that the garbage had
    # hidden for a while (no garbage packet can be addressed to 200): nothing else.
    heard = PacketParser().feed(read_for(port, 0.3))
    assert all(p == Packet(CONTROLLER_ID, 0, b"") for p in heard), heard


def test_pc_link_on_a_unix_socket(firmware_image):
    with QemuFirmware(firmware_image, pc_link=Endpoint.unix_server()) as fw:
        path = fw.ports.pc_link
        with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as s:
            s.connect(path)
            s.settimeout(0.2)
            parser = PacketParser()
            got: list = []
            end = time.monotonic() + 10
            while not got and time.monotonic() < end:
                s.sendall(ping(CONTROLLER_ID))
                try:
                    got = [p for p in parser.feed(s.recv(64)) if isinstance(p, Packet)]
                except TimeoutError:
                    pass
            assert got[:1] == [Packet(CONTROLLER_ID, 0, b"")]


def test_runner_leaves_nothing_behind(firmware_image):
    fw = QemuFirmware(firmware_image)
    fw.start()
    pid = fw.pid
    pty = fw.ports.pc_link
    workdir = fw.log_path.parent
    assert fw.running and os.path.exists(pty) and workdir.is_dir()
    assert fw.stop() is not None
    assert not fw.running
    with pytest.raises(ProcessLookupError):
        os.kill(pid, 0)  # exited and reaped
    assert not workdir.exists()
    assert fw.stop() == fw.stop()  # idempotent
    with pytest.raises(QemuError):
        fw.ports  # noqa: B018


def test_runner_reports_a_missing_image(tmp_path):
    with pytest.raises(QemuError, match="make firmware"):
        QemuFirmware(tmp_path / "nothing.bin").start()


def test_runner_stops_qemu_when_dropped(firmware_image):
    fw = QemuFirmware(firmware_image)
    fw.start()
    pid = fw.pid
    del fw  # the finalizer must stop it
    deadline = time.monotonic() + 10
    while time.monotonic() < deadline:
        try:
            os.kill(pid, 0)
        except ProcessLookupError:
            break
        time.sleep(0.05)
    else:
        pytest.fail("QEMU still running after its QemuFirmware was dropped")
