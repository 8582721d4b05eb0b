"""Helpers shared by the firmware tests: building the images once per session, reading
their symbols and sections with the ARM binutils, and a Protocol 1.0 client on the
emulated PC link with time limits fit for a loaded machine."""

from __future__ import annotations

import contextlib
import functools
import hashlib
import importlib.util
import os
import shutil
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any, TypeVar

import pytest
from host_queue import HostQueue

from snakebot.facts import devices
from snakebot.facts.boards import APP_BASE as APP_BASE  # re-exported for the firmware tests
from snakebot.facts.boards import PC_LINK_BAUD
from snakebot.facts.controller import load as load_controller
from snakebot.facts.memory import CM530_FLASH_SIZE, FLASH_BASE
from snakebot.firmware import image as firmware_image
from snakebot.formats.protocol import DxlTimeout
from snakebot.link.transport import DxlClient, settings
from snakebot.link.transport.timing import PROGRAM_MARGIN_S
from snakebot.paths import REPO_ROOT
from snakebot.sim.bus.bus import Bus
from snakebot.sim.bus.faults import FaultConfig
from snakebot.sim.options import SimOptions
from snakebot.sim.qemu import Endpoint, QemuFirmware
from snakebot.sim.transports.unixsock import UnixSocketServer

BUILD = REPO_ROOT / "build"
FIRMWARE = REPO_ROOT / "firmware"


@functools.cache
def board_figures() -> Any:
    """protocol/board_figures.py as a module (a script's helper, not part of the package)."""
    spec = importlib.util.spec_from_file_location(
        "board_figures", REPO_ROOT / "protocol" / "board_figures.py"
    )
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def board_value(board: str, name: str) -> int:
    """The number ``#define name`` stands for in firmware/boards/<board>/board.h (an
    expression of literals and the board's other numbers), evaluated as the docs'
    generator evaluates it."""
    return board_figures().board_value(board, name)


def cm530_image() -> bytes:
    """The CM-530 image `make flash` sends (build/cm530/firmware.bin), for the emulated
    board's tests; the test is skipped while it is not built."""
    path = firmware_image("cm530", "firmware.bin")
    if not path.is_file():
        pytest.skip("build/cm530/firmware.bin is not built: make firmware")
    return path.read_bytes()


QEMU_DIR = BUILD / "qemu"
CM530_DIR = BUILD / "cm530"
STUB_BASE = 0x08000000
CONTROLLER_ID = load_controller().default_id
PC_BAUD = PC_LINK_BAUD


def build_firmware() -> str:
    """Run `make -C firmware` (does nothing when up to date); returns its output."""
    if shutil.which("arm-none-eabi-gcc") is None:
        pytest.fail("arm-none-eabi-gcc missing: run `make setup`")
    done = subprocess.run(
        ["make", "-C", str(REPO_ROOT / "firmware"), "--no-print-directory", "all"],
        capture_output=True,
        text=True,
        check=False,
    )
    if done.returncode != 0:
        pytest.fail(f"firmware build failed:\n{done.stdout}\n{done.stderr}")
    return done.stdout


def symbols(elf: Path) -> dict[str, int]:
    """Symbol name -> address, from arm-none-eabi-nm."""
    out = subprocess.run(
        ["arm-none-eabi-nm", str(elf)], capture_output=True, text=True, check=True
    ).stdout
    table = {}
    for line in out.splitlines():
        parts = line.split()
        if len(parts) == 3:
            table[parts[2]] = int(parts[0], 16)
    return table


def sections(elf: Path) -> dict[str, tuple[int, int]]:
    """Section name -> (address, size), from arm-none-eabi-size -A."""
    out = subprocess.run(
        ["arm-none-eabi-size", "-A", "-d", str(elf)], capture_output=True, text=True, check=True
    ).stdout
    table = {}
    for line in out.splitlines():
        parts = line.split()
        if len(parts) == 3 and parts[0].startswith("."):
            table[parts[0]] = (int(parts[2]), int(parts[1]))
    return table


HEALTHY_TIMEOUT_SHARE = 0.05
"""The share of telemetry READs that may go unanswered in a healthy emulated run.

The firmware in QEMU waits BOARD_BUS_REPLY_TIMEOUT_US (30 ms) for an emulated servo that
answers from a Python thread; on a busy machine that thread is now and then descheduled
for longer, and a READ times out although nothing is wrong. A dead servo, a wrong baud
rate or a bus that drops replies shows up as most READs timing out, far above this."""

MIN_HEALTHY_READS = 10


def assert_healthy_bus(reads: int, timeouts: int) -> None:
    """The controller polled its servos, and (almost) every telemetry READ was answered."""
    assert reads >= MIN_HEALTHY_READS, f"only {reads} telemetry reads"
    assert timeouts <= HEALTHY_TIMEOUT_SHARE * reads, f"{timeouts} of {reads} reads timed out"


def client(port: str) -> DxlClient:
    """A Protocol 1.0 client on the emulated PC link (a pty path)."""
    # The controller, not an AX-12: its registers (and their ranges) are its own. A raw
    # client: it takes by hand the margin ControllerClient.open gives a pseudo-terminal.
    return DxlClient(
        port, PC_BAUD, margin_s=PROGRAM_MARGIN_S, echo=False, device=devices.controller()
    )


def wait_for_boot(port: str, timeout: float = 20.0) -> None:
    """Wait until the firmware answers PING on its PC link (DxlTimeout after ``timeout``)."""
    with client(port) as c:
        deadline = time.monotonic() + timeout
        while True:
            try:
                c.ping(CONTROLLER_ID, retries=0)
                return
            except DxlTimeout:
                if time.monotonic() > deadline:
                    raise


BOARDS = ("cm530", "qemu")
"""The boards the firmware-in-the-loop tests of board-dependent behaviour (the PC link,
upload, play) run on: the CM-530's image on the emulated STM32F103RE, the default, and
the qemu board's build under QEMU, a second, independent emulator of the same core."""


def kept_capacity(board: str) -> int:
    """The most bytes a table on ``board`` may take and still never give way to an upload
    staged while it is active: the arena less the staging area (Table Capacity), or the
    capacity where the arena holds both whole (protocol/controller.md, "Where a table is
    staged")."""
    capacity = board_value(board, "BOARD_TABLE_CAPACITY")
    return min(capacity, board_value(board, "BOARD_TABLE_ARENA") - capacity)


CM530_MARGIN_MS = 3000
"""The reply margin the clients get from the emulated CM-530 in the tests' own process
(``SNAKEBOT_MARGIN_MS``; tests/firmware/test_cm530_cli.py's too)."""


GIVE_WAY_NICE = 10
"""How many nice levels the emulated CM-530's thread runs below the test's own: it slows
its clock when the host keeps it waiting, QEMU runs in real time and does not (beside
the in-process chips at the serial stage's priority, QEMU's campaigns lost a PING)."""


def give_way(mcu: Any) -> None:
    """Let QEMU and the other real-time work of a loaded machine go first: the in-process
    emulated CM-530 (``McuFirmware``, or ``EmulatedRobot``'s; nothing under QEMU) runs
    its thread :data:`GIVE_WAY_NICE` levels lower (Linux keeps a nice level per thread)."""
    mcu = getattr(mcu, "_mcu", mcu)  # an EmulatedRobot's board (None under QEMU)
    thread = getattr(mcu, "_thread", None)  # the thread the board runs on
    if thread is None or thread.native_id is None:
        return
    nice = os.getpriority(os.PRIO_PROCESS, 0) + GIVE_WAY_NICE
    with contextlib.suppress(OSError):  # the thread may just have ended
        os.setpriority(os.PRIO_PROCESS, thread.native_id, min(nice, 19))


def widen_margin(board: str, env: pytest.MonkeyPatch) -> None:
    """Give the clients in this process :data:`CM530_MARGIN_MS` when ``board`` is the
    emulated CM-530, which runs in this process (as :func:`running` does)."""
    if board == "cm530":
        env.setenv(settings.ENV_MARGIN_MS, str(CM530_MARGIN_MS))


@contextlib.contextmanager
def emulated_robot(robot: str, board: str) -> Iterator[Any]:
    """`sim serve`'s emulated robot (``EmulatedRobot``) on ``board``, as the tests run
    it: on the emulated CM-530, the clients in this process get the wider margin
    (:func:`widen_margin`) and the chip's thread gives way (:func:`give_way`)."""
    from snakebot.sim.serve import EmulatedRobot

    with pytest.MonkeyPatch.context() as env:
        widen_margin(board, env)
        with EmulatedRobot(robot, board=board) as emulated:
            give_way(emulated)
            yield emulated


class Running:
    """A board's firmware image running on emulated servos, as the tests look at it on
    either board: its PC link's pty, its servo bus (read it holding :attr:`lock`) and what
    the emulator counts of the PC link's traffic."""

    def __init__(
        self,
        board: str,
        pc_link: str,
        bus: Bus,
        lock: contextlib.AbstractContextManager[Any],
        firmware: Any,
    ) -> None:
        self.board = board
        self.pc_link = pc_link
        self.bus = bus
        self.lock = lock
        self.firmware = firmware  # QemuFirmware or McuFirmware

    def bus_now(self) -> float:
        """The servo bus's clock (seconds of emulated time)."""
        with self.lock:
            return self.bus.now

    def dropped(self) -> int:
        """Bytes the firmware sent the PC that the terminal had no room for (nobody read
        them), which the emulator dropped."""
        fw = self.firmware
        return fw.dropped("pc") if self.board == "qemu" else fw.dropped

    def pc_out(self) -> int:
        """Bytes the firmware's PC link has sent so far (taken by the terminal or dropped)."""
        fw = self.firmware
        if self.board == "qemu":
            relay = fw._relays["pc"]  # noqa: SLF001 - QEMU's relay counts what it took
            return relay.relayed + relay.dropped
        return fw.board.mcu.usart3.sent

    def unheard(self) -> int:
        """Bytes the PC sent that the firmware's UART never received: sent at another
        baud rate than USART3's, or before the firmware set it up (as the PINGs that wait
        for its boot). The emulated CM-530 counts them; QEMU has no baud rate on its pty
        and takes bytes only once its UART does (0)."""
        if self.board == "qemu":
            return 0
        fw = self.firmware
        return fw.wrong_baud + fw.board.mcu.usart3.lost

    def flash(self) -> bytes:
        """The emulated CM-530's flash from the application's base to its end, all a power
        cycle keeps (start the board again with it as ``image``)."""
        assert self.board == "cm530", "QEMU's flash is not read here"
        with self.lock:
            return self.firmware.board.mcu.read(APP_BASE, FLASH_BASE + CM530_FLASH_SIZE - APP_BASE)

    def host_queue(self) -> HostQueue:
        """How long the host keeps the emulator's CPU waiting to run: QEMU's process, or
        the emulated CM-530's thread in this process."""
        fw = self.firmware
        if self.board == "qemu":
            return HostQueue(fw.pid)
        thread = fw._thread  # noqa: SLF001 - the thread the board runs on
        return HostQueue(os.getpid(), thread.native_id)


@contextlib.contextmanager
def running(
    board: str,
    folder: Path,
    robot: str = "snake5",
    faults: FaultConfig | None = None,
    bus: Bus | None = None,
    image: bytes | None = None,
) -> Iterator[Running]:
    """``board``'s firmware image running, its bus ``bus`` or else served by ``robot``'s
    emulated servos (with ``faults`` on the wire, if given): yields it once the firmware
    answers on its PC link. ``folder`` holds QEMU's bus socket. ``image``: the CM-530's
    flash from the application's base (:meth:`Running.flash`), instead of its build."""
    build_firmware()
    if bus is None:
        bus = SimOptions(robot=robot, faults=faults or FaultConfig()).build_bus()
    if board == "qemu":
        assert image is None, "QEMU runs the qemu board's build"
        sock = folder / "bus.sock"
        with (
            UnixSocketServer(bus, sock) as server,
            QemuFirmware(QEMU_DIR / "flash.bin", bus=Endpoint.unix_client(sock)) as fw,
        ):
            wait_for_boot(fw.ports.pc_link)
            yield Running(board, fw.ports.pc_link, bus, server.lock, fw)
            assert server.running
        return
    pytest.importorskip("unicorn")
    from snakebot.sim.mcu.runner import McuFirmware
    from snakebot.sim.serve import board_image, default_firmware

    if image is None:
        image = board_image(default_firmware(board), board)
    with (
        McuFirmware(image, bus=bus) as fw,
        pytest.MonkeyPatch.context() as env,
    ):
        # The emulated chip runs in this process, in Python where it touches a
        # peripheral, beside the in-process clients: on a loaded machine it may fall
        # below real time while the bus is busy (it then slows its clock rather than pile
        # up a backlog), so its replies get a wider margin than a board's.
        widen_margin(board, env)
        give_way(fw)
        wait_for_boot(fw.pc_link)
        yield Running(board, fw.pc_link, bus, fw.lock, fw)
        assert fw.error is None, fw.error


@contextlib.contextmanager
def booted(
    board: str, folder: Path, robot: str = "snake5", faults: FaultConfig | None = None
) -> Iterator[str]:
    """``board``'s firmware image running, its bus served by ``robot``'s emulated servos
    (with ``faults`` on the wire, if given): yields the PC link's pty once the firmware
    answers. ``folder`` holds QEMU's bus socket."""
    with running(board, folder, robot, faults) as fw:
        yield fw.pc_link


HAL_DIR = REPO_ROOT / "firmware" / "hal"

HAL_IO_CALLBACKS = """
extern "Python+C" uint32_t hal_io_read32(uint32_t addr);
extern "Python+C" void hal_io_write32(uint32_t addr, uint32_t value);
extern "Python+C" uint16_t hal_py_read16(uint32_t addr);
extern "Python+C" void hal_io_write16(uint32_t addr, uint16_t value);
void hal_host_flash_view(const uint8_t *mem, uint32_t base, uint32_t len);
"""

HAL_IO_READ16 = """
/* A model's flash, read in C: a read of it has no side effect in the models, and the
 * stores read every half-word of 32 KB at each step (millions of Python calls). Any
 * other address, or a misaligned one, goes to the model's read16. */
uint16_t hal_py_read16(uint32_t addr); /* the model's read16, defined by cffi below */
static const uint8_t *host_flash_mem;
static uint32_t host_flash_base, host_flash_len;

void hal_host_flash_view(const uint8_t *mem, uint32_t base, uint32_t len)
{
    host_flash_mem = mem;
    host_flash_base = base;
    host_flash_len = len;
}

uint16_t hal_io_read16(uint32_t addr)
{
    const uint32_t off = addr - host_flash_base;
    if (host_flash_mem != NULL && addr >= host_flash_base && off + 1U < host_flash_len
        && (addr & 1U) == 0U) {
        return (uint16_t)(host_flash_mem[off] | (uint16_t)(host_flash_mem[off + 1U] << 8));
    }
    return hal_py_read16(addr);
}
"""


HAL_CACHE = REPO_ROOT / "build" / "test-hal"
"""Host builds of the drivers, by what they were built from (`make clean` removes them)."""


def _build_key(name: str, *parts: object) -> str:
    """A digest of everything a host build depends on: its settings, this module's C
    around the drivers, every firmware source and header, Python's and cffi's versions."""
    import cffi

    digest = hashlib.sha256(
        repr((name, parts, HAL_IO_CALLBACKS, HAL_IO_READ16, sys.version, cffi.__version__)).encode()
    )
    for path in sorted(HAL_DIR.parent.rglob("*.[ch]")):
        digest.update(str(path.relative_to(HAL_DIR.parent)).encode() + b"\0")
        digest.update(path.read_bytes())
    return digest.hexdigest()[:20]


def build_hal_host(
    name: str,
    sources: list[str],
    headers: list[str],
    cdef: str,
    tmpdir: Path,
    defines=(),
    include_dirs=(),
):
    """Compile HAL drivers for the host with -DHAL_HOST_TEST: every register access goes
    to the four hal_io_* callbacks, which the test implements in Python (a register model
    of the peripheral). ``sources`` are relative to firmware/hal, ``include_dirs`` (more
    than firmware/hal) to firmware. Returns the compiled module (``.ffi``, ``.lib``)."""
    import importlib.util

    from cffi import FFI

    ffi = FFI()
    ffi.cdef(cdef + HAL_IO_CALLBACKS)
    ffi.set_source(
        name,
        "\n".join(f'#include "{h}"' for h in ("hal_io.h", *headers)) + HAL_IO_READ16,
        sources=[str(HAL_DIR / s) for s in sources],
        include_dirs=[str(HAL_DIR), *(str(HAL_DIR.parent / d) for d in include_dirs)],
        define_macros=[("HAL_HOST_TEST", None), *defines],
        extra_compile_args=["-std=c99", "-Wall", "-Wextra"],
    )
    key = _build_key(name, cdef, headers, sources, defines, include_dirs)
    cached = HAL_CACHE / f"{name}-{key}.so"
    library = Path(tmpdir) / cached.name
    if cached.exists():
        shutil.copyfile(cached, library)
    else:
        built = Path(ffi.compile(tmpdir=str(tmpdir)))
        HAL_CACHE.mkdir(parents=True, exist_ok=True)
        part = cached.with_name(f"{cached.name}.{os.getpid()}.part")
        shutil.copyfile(built, part)
        part.replace(cached)  # whole or not at all, whichever worker finishes first
        shutil.copyfile(built, library)
    # each build loads its own copy: a library's static state is never shared with
    # another test module's
    spec = importlib.util.spec_from_file_location(name, library)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


M = TypeVar("M")


class RegisterModels:
    """Which register model answers the accesses of a HAL built by
    :func:`build_hal_on_models`: the one most recently put in :meth:`use`."""

    def __init__(self) -> None:
        self._stack: list[Any] = []
        self._hals: list[Any] = []  # the built HALs, told which flash to read in C

    @property
    def current(self) -> Any:
        return self._stack[-1]

    def serve(self, hal: Any) -> None:
        """Let ``hal`` read the current model's flash (a ``mem`` bytearray at ``base``)
        in C; other accesses still go to the model."""
        self._hals.append(hal)
        self._show()

    def _show(self) -> None:
        model = self._stack[-1] if self._stack else None
        mem = getattr(model, "mem", None) if getattr(model, "plain_reads", False) else None
        for hal in self._hals:
            if isinstance(mem, bytearray):
                # holding the buffer: a model that resized its flash would fail loudly
                hal.view = hal.ffi.from_buffer("uint8_t[]", mem)
                hal.lib.hal_host_flash_view(hal.view, model.base, len(mem))
            else:
                hal.view = None
                hal.lib.hal_host_flash_view(hal.ffi.NULL, 0, 0)

    @contextlib.contextmanager
    def use(self, model: M) -> Iterator[M]:
        """Let ``model`` answer the driver's register accesses inside the block."""
        self._stack.append(model)
        self._show()
        try:
            yield model
        finally:
            self._stack.remove(model)
            self._show()


def build_hal_on_models(
    name: str,
    sources: list[str],
    headers: list[str],
    cdef: str,
    tmpdir: Path,
    models: RegisterModels,
    *,
    defines=(),
    include_dirs=(),
    io16: bool = False,
):
    """:func:`build_hal_host`, with the hal_io_* callbacks going to ``models.current``
    (its ``read32``/``write32``, and ``read16``/``write16`` with ``io16``; without it a
    16-bit access fails the test)."""
    mod = build_hal_host(name, sources, headers, cdef, tmpdir, defines, include_dirs)

    @mod.ffi.def_extern()
    def hal_io_read32(addr):
        return models.current.read32(addr)

    @mod.ffi.def_extern()
    def hal_io_write32(addr, value):
        models.current.write32(addr, value)

    @mod.ffi.def_extern()
    def hal_py_read16(addr):
        if not io16:
            raise AssertionError("no 16-bit accesses expected")
        return models.current.read16(addr)

    @mod.ffi.def_extern()
    def hal_io_write16(addr, value):
        if not io16:
            raise AssertionError("no 16-bit accesses expected")
        models.current.write16(addr, value)

    if io16:
        models.serve(mod)
    return mod


def hal_fixture(
    name: str,
    sources: list[str],
    headers: list[str],
    cdef: str,
    models: RegisterModels,
    *,
    defines=(),
    include_dirs=(),
    io16: bool = False,
):
    """A module-scoped ``hal`` fixture: the drivers built once by
    :func:`build_hal_on_models`, answered by ``models``. Use as
    ``hal = hal_fixture(...)`` at the top level of a test module."""

    @pytest.fixture(scope="module", name="hal")
    def hal(tmp_path_factory):
        tmpdir = tmp_path_factory.mktemp(name.strip("_"))
        return build_hal_on_models(
            name,
            sources,
            headers,
            cdef,
            tmpdir,
            models,
            defines=defines,
            include_dirs=include_dirs,
            io16=io16,
        )

    return hal
