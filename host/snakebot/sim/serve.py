"""The emulated robot with its real firmware: the emulated CM-530 or QEMU, the emulated
servo bus and the world.

By default (``board="cm530"``) the exact CM-530 image runs on the emulated STM32F103RE
(:mod:`snakebot.sim.mcu`) in this process, its USART1 driving the emulated bus directly on
the chip's clock and its USART3 on a pseudo-terminal. With ``board="qemu"``, a second and
independent emulator of the same portable core, :class:`EmulatedRobot` starts, in this
order,

1. the robot's virtual AX-12s on an emulated bus (:mod:`snakebot.sim.bus.bus`), served on a Unix
   socket in a private work directory (:class:`~snakebot.sim.transports.unixsock.UnixSocketServer`,
   the bus clock tied to the wall clock);
2. the world (:class:`snakebot.sim.world.World`, or with ``world="mujoco"``
   :class:`snakebot.sim.physics.PhysicsWorld`): the body on the floor, sampling the servos
   every 10 ms of bus time from the moment the firmware connects;
3. ``qemu-system-arm`` running the firmware (:class:`snakebot.sim.qemu.QemuFirmware`) with
   USART1, the Dynamixel bus, connected to that socket and USART3, the PC link, on a
   pseudo-terminal that host tools open like the CM-530's USB-serial port;

and waits until the firmware answers PING on the PC link. :meth:`EmulatedRobot.stop`
(also on leaving a ``with`` block) stops QEMU (QMP quit, then SIGTERM, then SIGKILL),
then the bus server, and removes the work directory; QEMU also dies with the thread that
started it, so even a killed host leaves no emulator behind.

::

    with EmulatedRobot("snake5") as robot:          # build/cm530/firmware.bin
        print(robot.info.pc_link)                   # /dev/pts/N, 57600 baud, ID 200
        ...                                         # snakebot upload/play/monitor --port
        print(robot.record().displacement())        # how far the body went

The CM-530 takes its image as ``make firmware`` builds it (``build/cm530/firmware.bin``,
``.hex`` or ``.elf``). The qemu board takes the application ELF
(``build/qemu/firmware.elf``, linked at 0x08003000: the boot stub from the same directory
is put in front of it, as the CM-530's bootloader sits in front of the application) or a
whole-flash raw image (``build/qemu/flash.bin``). An image built for the other board is
refused at once, naming the board it was built for.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import struct
import time
from dataclasses import asdict, dataclass, replace
from pathlib import Path
from types import TracebackType
from typing import TYPE_CHECKING, Any

import numpy as np

from snakebot.errors import quoted
from snakebot.extras import require
from snakebot.facts.boards import APP_BASE, PC_LINK_BAUD, ROBOT_BOARD, TABLE_CAPACITY
from snakebot.facts.controller import load as load_controller
from snakebot.facts.memory import FLASH_BASE, QEMU_FLASH_SIZE, QEMU_RAM_SIZE, RAM_BASE
from snakebot.firmware import image as firmware_image
from snakebot.formats.protocol import DxlTimeout, ProtocolError
from snakebot.link.flash.image import image_info
from snakebot.link.transport import DxlClient
from snakebot.model.robots import Robot, load_robot
from snakebot.sim.bus.bus import Bus
from snakebot.sim.errors import SimFailure, SimInputError, SimOptionError
from snakebot.sim.history import History
from snakebot.sim.mcu.errors import ImageError
from snakebot.sim.options import SimOptions
from snakebot.sim.physics import PhysicsWorld
from snakebot.sim.physics.select import DEFAULT_WORLD, check_world, make_world
from snakebot.sim.qemu import Endpoint, QemuFirmware
from snakebot.sim.servo.fast import VirtualServo
from snakebot.sim.transports.unixsock import UnixSocketServer
from snakebot.sim.workdirs import make_workdir
from snakebot.sim.world import World, WorldRecord
from snakebot.userfiles import UnreadableInput, read_bounded

if TYPE_CHECKING:
    from snakebot.sim.mcu.runner import McuFirmware

BOARDS = tuple(sorted(TABLE_CAPACITY))
"""Where the firmware runs: ``cm530``, the emulated STM32F103RE running the CM-530's own
image, or ``qemu``, QEMU's stm32vldiscovery running the qemu board's build of the same
portable core (a second, independent emulator of it)."""

DEFAULT_BOARD = ROBOT_BOARD
"""The board emulated unless told otherwise: the robot's own, the CM-530."""

DEFAULT_IMAGES = {"cm530": "firmware.bin", "qemu": "firmware.elf"}
"""The file each board runs unless told otherwise, as ``make firmware`` names it under
``build/<board>/`` and a wheel ships it (:data:`snakebot.firmware.SHIPPED`)."""


def default_firmware(board: str = DEFAULT_BOARD) -> Path:
    """The image ``board`` runs unless told otherwise: ``make firmware``'s in a checkout,
    else the one shipped in the package (:mod:`snakebot.firmware`)."""
    return firmware_image(board, DEFAULT_IMAGES[board])


QEMU_FIRMWARE = default_firmware("qemu")
"""The qemu board's application image (its boot stub, ``stub.elf``, lies beside it)."""


FLASH_SIZE = QEMU_FLASH_SIZE
RAM_SIZE = QEMU_RAM_SIZE
CONTROLLER_ID = load_controller().default_id
"""The firmware's Protocol 1.0 ID on the PC link (factory default)."""

BOOT_TIMEOUT_S = 20.0
"""How long :meth:`EmulatedRobot.start` waits for the firmware to answer on the PC link."""

BOOT_PING_MARGIN_S = 0.2
"""Reply margin of the boot-time PINGs (QEMU may be descheduled on a busy machine)."""


class ServeError(SimFailure):
    """The emulated robot could not be started as asked (the message says how to fix it)."""


@dataclass(frozen=True)
class ServeInfo:
    """Where to reach the running emulated robot."""

    pc_link: str
    """The firmware's PC link (USART3): a pseudo-terminal, 57600 baud, controller ID 200."""
    bus_socket: str
    """The Unix socket carrying USART1 to the emulated servos."""
    qemu_pid: int
    robot: str
    servo_ids: tuple[int, ...]
    firmware: str
    board: str = DEFAULT_BOARD
    """Which board runs the firmware (:data:`BOARDS`)."""
    controller_id: int = CONTROLLER_ID
    baudrate: int = PC_LINK_BAUD

    def as_dict(self) -> dict[str, Any]:
        out = asdict(self)
        out["servo_ids"] = list(self.servo_ids)
        return out

    def where(self) -> str:
        """Where the firmware runs, in words: "on the emulated STM32F103RE" or "in QEMU
        (pid N)"."""
        if self.board == "qemu":
            return f"in QEMU (pid {self.qemu_pid})"
        return "on the emulated STM32F103RE"


@dataclass(frozen=True)
class BodyPose:
    """The body's pose in the world at ``t`` seconds of world time: ``x`` and ``y`` (m),
    x forward along the head link's first heading, and the heading ``theta`` (rad)."""

    t: float
    x: float
    y: float
    theta: float

    def as_dict(self) -> dict[str, float]:
        return {
            "t": round(self.t, 3),
            "x": round(self.x, 6),
            "y": round(self.y, 6),
            "theta": round(self.theta, 6),
        }


# -- the flash image ----------------------------------------------------------------------


MAX_ELF_BYTES = 16 << 20
"""The largest firmware ELF read: the 128 KB of code with its debug sections stays well
under a few megabytes."""


def _read_firmware(path: Path) -> bytes:
    try:
        return read_bounded(path, MAX_ELF_BYTES, "firmware image")
    except UnreadableInput as exc:
        raise SimInputError(str(exc)) from None
    except OSError as exc:
        raise ServeError(f"cannot read firmware image {path}: {exc.strerror or exc}") from None


def _check_raw_image(path: Path, data: bytes) -> None:
    """A raw flash image must fit the flash and start with a vector table whose stack
    pointer is in RAM and whose reset handler is in flash: else QEMU boots nothing."""
    if len(data) > FLASH_SIZE:
        raise SimInputError(
            f"{path} is {len(data)} bytes, more than the emulated board's {FLASH_SIZE} bytes "
            "of flash: give build/qemu/firmware.elf or flash.bin"
        )
    sp, reset = struct.unpack_from("<II", data) if len(data) >= 8 else (0, 0)
    in_ram = RAM_BASE < sp <= RAM_BASE + RAM_SIZE
    in_flash = FLASH_BASE <= reset < FLASH_BASE + len(data) and reset & 1
    if not (in_ram and in_flash):
        raise SimInputError(
            f"{path} is neither an ELF file nor a flash image that starts with a vector "
            "table (it is empty, or holds something else): give build/qemu/firmware.elf "
            "or the flash.bin `make firmware` writes"
        )


def _elf_segments(path: Path, data: bytes | None = None) -> list[tuple[int, bytes]]:
    """(load address, bytes) of each loadable segment with file contents of a 32-bit
    little-endian ARM ELF, or ServeError naming what is wrong with the file."""
    if data is None:
        data = _read_firmware(path)
    if data[:4] != b"\x7fELF" or len(data) < 52:
        raise SimInputError(
            f"{path} is not an ELF file: give build/qemu/firmware.elf or a raw flash image (.bin)"
        )
    if data[4] != 1 or data[5] != 1:
        raise SimInputError(f"{path} is not a 32-bit little-endian ELF: is it an ARM firmware?")
    machine = struct.unpack_from("<H", data, 18)[0]
    if machine != 40:  # EM_ARM
        raise SimInputError(
            f"{path} is an ELF for machine {machine}, not ARM: build the "
            "firmware with `make firmware`"
        )
    (phoff,) = struct.unpack_from("<I", data, 28)
    phentsize, phnum = struct.unpack_from("<HH", data, 42)
    segments = []
    for i in range(phnum):
        p_type, p_offset, _vaddr, p_paddr, p_filesz = struct.unpack_from(
            "<IIIII", data, phoff + i * phentsize
        )
        if p_type == 1 and p_filesz:  # PT_LOAD with contents (its load address: p_paddr)
            segments.append((p_paddr, data[p_offset : p_offset + p_filesz]))
    if not segments:
        raise SimInputError(f"{path} has nothing to load: rebuild it with `make firmware`")
    return segments


def check_firmware(firmware: str | os.PathLike[str] | None, board: str = DEFAULT_BOARD) -> Path:
    """The firmware image ``firmware`` names (None: ``board``'s default), if it is a file
    that ``board`` can run (not empty, not another board's build); SimInputError with the
    fix otherwise. For callers that write something first (the demo's gait table), so
    that a bad image leaves nothing behind."""
    src = _existing(firmware, board)
    board_image(src, board)
    return src


def board_image(src: Path, board: str) -> bytes:
    """What ``board`` loads from the firmware file ``src``: the CM-530's application bytes
    (checked as the board would fail on them) or QEMU's whole-flash image."""
    if board == "qemu":
        return _qemu_flash(src)
    from snakebot.sim.mcu.image import read_image

    try:
        return read_image(src)
    except ImageError as exc:  # another board's, empty, truncated: bad input
        raise SimInputError(str(exc)).about("firmware") from None


def _existing(firmware: str | os.PathLike[str] | None, board: str) -> Path:
    """The file ``firmware`` names (None: ``board``'s default image), if it exists."""
    default = default_firmware(check_board(board))
    src = Path(firmware) if firmware is not None else default
    if not src.is_file():
        hint = (
            "run `make firmware` to build it"
            if src == default
            else f"check the path; `make firmware` builds build/{board}/"
            f"{DEFAULT_IMAGES[board]} in a checkout (the {board} board's default image: "
            f"{default})"
        )
        raise SimInputError(f"firmware image {src} not found: {hint}").about("firmware")
    return src


def check_board(board: str) -> str:
    """``board`` if it is one of :data:`BOARDS` and this installation can run it (the
    emulated CM-530 needs the ``mcu`` extra), else an error saying what to do."""
    if board not in BOARDS:
        raise SimOptionError(
            f"unknown board {quoted(board)}: choose one of {', '.join(BOARDS)}"
        ).about("board")
    if board == "cm530":
        require("unicorn", "the emulated CM-530", params=("board",))
    return board


def _check_qemu_build(src: Path, app: bytes) -> None:
    """An image whose identity block names another board than qemu (``app``: its bytes
    from the application base on) would not answer on QEMU: refused at once, naming it."""
    info = image_info(app, APP_BASE)
    if info is not None and info.board != "qemu":
        raise SimInputError(
            f"{src} was built for the {info.board} board, not the qemu board: run it on the "
            f"{info.board} board, or give the qemu board's image (build/qemu/firmware.elf)"
        ).about("firmware")


def flash_image(firmware: str | os.PathLike[str], out: str | os.PathLike[str]) -> Path:
    """The whole-flash raw image QEMU boots, written to ``out``.

    ``firmware`` is a raw image (``.bin``: copied as it is, loaded at 0x08000000) or an
    ELF. An ELF whose code starts at the application base (0x08003000) gets the boot stub
    (``stub.elf`` beside it, else the default build's) put in front, as ``make firmware``
    lays out ``flash.bin``; the gap is erased flash (0xFF)."""
    dest = Path(out)
    dest.write_bytes(_qemu_flash(_existing(firmware, "qemu")))
    return dest


def _qemu_flash(src: Path) -> bytes:
    """The whole-flash image of :func:`flash_image` from the firmware file ``src``."""
    data = _read_firmware(src)
    if data[:4] != b"\x7fELF":
        _check_qemu_build(src, data)  # an application image, as the CM-530's .bin is
        _check_raw_image(src, data)
        return data
    segments = _elf_segments(src, data)
    if min(addr for addr, _ in segments) >= APP_BASE:
        stub = next(
            (
                p
                for p in (src.parent / "stub.elf", QEMU_FIRMWARE.parent / "stub.elf")
                if p.is_file()
            ),
            None,
        )
        if stub is None:
            raise SimInputError(
                f"{src} is an application image but no boot stub (stub.elf) was "
                "found beside it: run `make firmware`"
            )
        segments = _elf_segments(stub) + segments
    image = bytearray(b"\xff" * FLASH_SIZE)
    end = 0
    for addr, blob in segments:
        start = addr - FLASH_BASE
        if start < 0 or start + len(blob) > FLASH_SIZE:
            raise SimInputError(
                f"{src}: a segment at 0x{addr:08x} ({len(blob)} bytes) is outside "
                "the emulated board's 128 KB flash: build it for the qemu board "
                "(`make firmware` builds build/qemu/firmware.elf)"
            )
        image[start : start + len(blob)] = blob
        end = max(end, start + len(blob))
    _check_qemu_build(src, bytes(image[APP_BASE - FLASH_BASE : end]))
    return bytes(image[:end])


class GoalLog:
    """Each servo's Goal Position register (the last goal the master sent it), sampled on
    the bus clock every ``period`` seconds from ``start``, like the world's samples."""

    def __init__(
        self,
        bus: Bus,
        ids: tuple[int, ...],
        period: float,
        start: float,
        keep: int | None = None,
    ) -> None:
        self._servos = [bus.servo(i) for i in ids]
        self._start = start
        # keep: the latest samples only; per sample its time, then each servo's goal
        self._history = History(1 + len(self._servos), keep)
        bus.every(period, self._sample, start=start)

    def _sample(self, t: float) -> None:
        row = self._history.slot()
        row[0] = t - self._start
        row[1:] = [s.regs.get("Goal Position") for s in self._servos]

    def arrays(self) -> tuple[np.ndarray, np.ndarray]:
        """(times in seconds since ``start``, goals: rows x servos)."""
        rows = self._history.array()
        return rows[:, 0], rows[:, 1:]


# -- the emulated robot -------------------------------------------------------------------


class EmulatedRobot:
    """The robot's emulated servos and body, driven by the real firmware on an emulated
    board.

    ``robot``: a built-in name or a robot TOML file (or a :class:`Robot`). ``firmware``:
    the image to run (default: the board's, :func:`default_firmware`). ``sim_query``: extra emulator
    options as in a ``sim://`` URL (``corrupt=0.001&seed=3``; see ``snakebot sim bus
    --help``). ``world_period``: seconds of bus time between the world's samples;
    ``world``: "kinematic" or "mujoco" (the physics moves the servos).
    ``history_s``: how many seconds of the latest world samples and goals :meth:`record`
    and :meth:`goals` keep (None: all), so a robot served for hours needs bounded memory.
    ``board``: "cm530" (the emulated STM32F103RE, the default) or "qemu".
    """

    def __init__(
        self,
        robot: str | Robot = "snake5",
        firmware: str | os.PathLike[str] | None = None,
        *,
        sim_query: str = "",
        world_period: float = 0.01,
        world: str = DEFAULT_WORLD,
        history_s: float | None = None,
        board: str = DEFAULT_BOARD,
    ) -> None:
        self.board = check_board(board)
        self.world_kind = check_world(world)
        self.robot = robot if isinstance(robot, Robot) else load_robot(robot)
        self.history = None if history_s is None else max(1, round(history_s / world_period))
        self.firmware = Path(firmware) if firmware is not None else default_firmware(board)
        self.sim_query = sim_query
        self.world_period = world_period
        self._workdir: str | None = None
        self._server: UnixSocketServer | None = None
        self._qemu: QemuFirmware | None = None
        self._mcu: McuFirmware | None = None
        self._world: World | PhysicsWorld | None = None
        self._bus: Bus | None = None
        self._goals: GoalLog | None = None
        self._info: ServeInfo | None = None

    # -- lifecycle ------------------------------------------------------------------------

    def start(self, boot_timeout: float = BOOT_TIMEOUT_S) -> ServeInfo:
        """Start the bus, the world and the board; return once the firmware answers PING."""
        if self._info is not None:
            return self._info
        self._workdir = make_workdir("serve")
        try:
            if self.board == "cm530":
                return self._start_cm530(boot_timeout)
            image = flash_image(self.firmware, Path(self._workdir) / "flash.bin")
            self._bus = self._build_bus()
            sock = Path(self._workdir) / "bus.sock"
            self._server = UnixSocketServer(self._bus, sock, private=True).start()
            with self._server.lock:  # type: ignore[attr-defined]
                self._world = make_world(
                    self.world_kind,
                    self._bus,
                    self.robot,
                    period=self.world_period,
                    keep=self.history,
                )
                self._goals = GoalLog(
                    self._bus,
                    self.robot.servo_ids,
                    self.world_period,
                    self._world.start_time,
                    keep=self.history,
                )
            self._qemu = QemuFirmware(image, bus=Endpoint.unix_client(sock))
            ports = self._qemu.start()
            self._wait_for_boot(ports.pc_link, boot_timeout)
            assert self._qemu.pid is not None
            self._info = ServeInfo(
                pc_link=ports.pc_link,
                bus_socket=str(sock),
                qemu_pid=self._qemu.pid,
                robot=self.robot.name,
                servo_ids=tuple(self.robot.servo_ids),
                firmware=str(self.firmware),
                board=self.board,
            )
        except BaseException:
            self.stop()
            raise
        return self._info

    def _build_bus(self) -> Bus:
        options = SimOptions.from_query(self.sim_query)
        if options.robot or options.ids:
            raise SimOptionError(
                "the robot's servos come from the robot given: leave robot= and ids= "
                "out of the emulator options"
            ).about("robot")
        return replace(options, robot=self.robot.source or self.robot.name).build_bus()

    def _attach_world(self, bus: Bus) -> None:
        self._world = make_world(
            self.world_kind, bus, self.robot, period=self.world_period, keep=self.history
        )
        self._goals = GoalLog(
            bus, self.robot.servo_ids, self.world_period, self._world.start_time, keep=self.history
        )

    def _start_cm530(self, boot_timeout: float) -> ServeInfo:
        from snakebot.sim.mcu.runner import McuFirmware  # needs unicorn: the mcu extra

        image = board_image(_existing(self.firmware, self.board), self.board)
        self._bus = self._build_bus()
        self._mcu = McuFirmware(image, bus=self._bus)
        with self._mcu.lock:
            self._attach_world(self._bus)
        self._mcu.start()
        self._wait_for_boot(self._mcu.pc_link, boot_timeout)
        self._info = ServeInfo(
            pc_link=self._mcu.pc_link,
            bus_socket="",
            qemu_pid=os.getpid(),
            robot=self.robot.name,
            servo_ids=tuple(self.robot.servo_ids),
            firmware=str(self.firmware),
            board=self.board,
        )
        return self._info

    def log(self) -> str:
        """What the emulator reported (QEMU's output, or the emulated chip's error)."""
        if self._mcu is not None:
            return "" if self._mcu.error is None else str(self._mcu.error)
        return self._qemu.log() if self._qemu is not None else ""

    def _emulator_running(self) -> bool:
        if self._mcu is not None:
            return self._mcu.running
        return self._qemu is not None and self._qemu.running

    def _wait_for_boot(self, pc_link: str, timeout: float) -> None:
        deadline = time.monotonic() + timeout
        with DxlClient(pc_link, PC_LINK_BAUD, margin_s=BOOT_PING_MARGIN_S, echo=False) as c:
            while True:
                try:
                    c.ping(CONTROLLER_ID, retries=0)
                    return
                except (DxlTimeout, ProtocolError):
                    pass
                if not self._emulator_running():
                    raise ServeError(
                        f"the emulator stopped while the firmware booted: "
                        f"{self.log().strip() or 'no output'}"
                    )
                if time.monotonic() > deadline:
                    raise ServeError(
                        f"the firmware did not answer PING (ID {CONTROLLER_ID}) on its PC link "
                        f"within {timeout:.0f} s: is {self.firmware} the {self.board} board's "
                        f"image (`make firmware`)? The emulator said: "
                        f"{self.log().strip() or 'nothing'}"
                    )

    def stop(self) -> None:
        """Stop the board (QEMU or the emulated chip), then the bus server and the world;
        remove the work directory. Idempotent; also runs when ``start`` fails half-way."""
        if self._qemu is not None:
            self._qemu.stop()
        if self._mcu is not None:
            self._mcu.stop()
            self._mcu = None
        if self._server is not None:
            self._server.close()
        if self._world is not None and self._world.running:
            with contextlib.suppress(Exception):  # the record stays; stopping must not fail
                self._world.stop()
        if self._workdir is not None:
            shutil.rmtree(self._workdir, ignore_errors=True)
            self._workdir = None
        self._info = None

    def __enter__(self) -> EmulatedRobot:
        self.start()
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.stop()

    # -- while it runs --------------------------------------------------------------------

    @property
    def info(self) -> ServeInfo:
        if self._info is None:
            raise ServeError("the emulated robot is not running: call start() first")
        return self._info

    @property
    def running(self) -> bool:
        """The emulator (and, with QEMU, the bus server) is alive."""
        if self._mcu is not None:
            return self._mcu.running
        return bool(self._qemu and self._qemu.running and self._server and self._server.running)

    @property
    def qemu(self) -> QemuFirmware:
        if self._qemu is None:
            raise ServeError("the emulated robot is not running: call start() first")
        return self._qemu

    @property
    def lock(self) -> Any:
        """Hold this while touching the bus, its servos or the world from another thread."""
        if self._mcu is not None:
            return self._mcu.lock
        if self._server is None:
            raise ServeError("the emulated robot is not running: call start() first")
        return self._server.lock

    @property
    def bus(self) -> Bus:
        if self._bus is None:
            raise ServeError("the emulated robot is not running: call start() first")
        return self._bus

    @property
    def world(self) -> World | PhysicsWorld:
        if self._world is None:
            raise ServeError("the emulated robot is not running: call start() first")
        return self._world

    def now(self) -> float:
        """The bus clock (seconds), which the world's sample times count from its start."""
        with self.lock:
            return self.bus.now

    def world_time(self) -> float:
        """Seconds of world time now (the time axis of :meth:`record`)."""
        with self.lock:
            return self.bus.now - self.world.start_time

    def positions(self) -> list[float]:
        """The servos' present positions (ticks), in the robot's joint order."""
        with self.lock:
            return self.bus.positions(self.robot.servo_ids)

    def servo(self, servo_id: int) -> VirtualServo:
        return self.bus.servo(servo_id)

    def record(self) -> WorldRecord:
        """What the world has seen so far (the body pose, joint angles, slip)."""
        with self.lock:
            return self.world.record()

    def pose(self) -> BodyPose | None:
        """The body's latest pose in the world; None before the world's first sample."""
        record = self.record()
        if not len(record.t):
            return None
        x, y, theta = (float(v) for v in record.pose[-1])
        return BodyPose(float(record.t[-1]), x, y, theta)

    def check_running(self) -> None:
        """SimFailure, with the emulator's log, if the emulator or the bus stopped."""
        if not self.running:
            raise SimFailure(
                "the emulator or the emulated bus stopped unexpectedly: "
                f"{self.log().strip() or 'no message'}"
            )

    def goals(self) -> tuple[np.ndarray, np.ndarray]:
        """The goal positions the firmware has sent the servos (ticks, one column per
        joint) at the world's sample times (seconds of world time): what it commanded."""
        if self._goals is None:
            raise ServeError("the emulated robot is not running: call start() first")
        with self.lock:
            return self._goals.arrays()

    def push(self, servo_id: int, torque_nm: float) -> None:
        """From now on the outside world pushes servo ``servo_id``'s horn with
        ``torque_nm`` (more than the servo can hold: it reports OVERLOAD)."""
        with self.lock:
            self.bus.servo(servo_id).set_external_torque(self.bus.now, torque_nm)
