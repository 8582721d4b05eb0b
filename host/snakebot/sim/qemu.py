"""Run the controller firmware under QEMU (``qemu-system-arm -M stm32vldiscovery``).

The qemu board image (``build/qemu/flash.bin``: a boot stub at 0x08000000 that enters the
CM-530 application at 0x08003000) runs with its two serial lines wired where the caller
wants them:

* USART1, the Dynamixel bus (QEMU's ``-serial`` 0): a Unix socket, for the emulated
  servos; nothing (``Endpoint.null()``); or any QEMU chardev.
* USART3, the PC link (``-serial`` 2): a pseudo-terminal that the host tools open exactly
  like the CM-530's USB-serial port, or a Unix socket.

The pseudo-terminals are made here, not by QEMU's ``pty`` backend: that one drops the
firmware's output until it notices, up to a second later, that someone opened the
terminal, and again after every close. Here this object holds the terminal open for
QEMU's lifetime, so clients may open and close it as often as they like. QEMU gets one
end of a socket pair and a relay thread (:class:`snakebot.sim.transports.relay.PtyRelay`)
carries bytes between it and the terminal's master side without ever making QEMU wait:
bytes the firmware sends while no client reads wait in the terminal's buffer (clients
flush their input before a transaction; :class:`snakebot.link.transport.DxlClient` does), and
once that is full they are dropped and counted (:meth:`QemuFirmware.dropped`), as a
USB-serial adapter drops what the PC does not read, instead of stalling the CPU.

::

    from snakebot.sim.qemu import Endpoint, QemuFirmware

    with QemuFirmware(bus=Endpoint.unix_client("/tmp/bus.sock")) as fw:
        ports = fw.ports                  # ports.pc_link == "/dev/pts/7", ports.bus == ...
        ...                               # talk Protocol 1.0 at ID 200 on ports.pc_link

QEMU is stopped through its QMP socket ("quit"), then SIGTERM, then SIGKILL, each with a
time limit, when the ``with`` block ends, on :meth:`QemuFirmware.stop`, when the object is
garbage-collected, and at interpreter exit. On Linux it also gets SIGKILL if the thread
that started it dies (``die_with_parent``), so a killed test run leaves no QEMU behind.

QEMU's model of this machine has limits the firmware is written for: RCC, GPIO, IWDG and
the flash controller are not modelled (no watchdog resets, no flash writes), baud rates
are ignored (bytes move as fast as the socket or pty carries them), and the core runs at
24 MHz. See firmware/boards/qemu/board.h.
"""

from __future__ import annotations

import contextlib
import ctypes
import itertools
import json
import os
import shutil
import signal
import socket
import subprocess
import sys
import time
import tty
import weakref
from dataclasses import dataclass
from pathlib import Path
from types import TracebackType
from typing import Any

from snakebot.facts.boards import PC_LINK_BAUD
from snakebot.firmware import image as firmware_image
from snakebot.settings import lookup_text
from snakebot.sim.bus.clock import BITS_PER_BYTE
from snakebot.sim.errors import SimFailure
from snakebot.sim.transports.relay import PtyRelay
from snakebot.sim.workdirs import make_workdir

QEMU_BINARY = "qemu-system-arm"
"""The emulator; the environment variable ``SNAKEBOT_QEMU`` names another."""

MACHINE = "stm32vldiscovery"

DEFAULT_IMAGE = firmware_image("qemu", "flash.bin")
"""The whole 128 KB flash as the qemu board sees it: boot stub, padding, application
(built in this checkout, else shipped in the package)."""

START_TIMEOUT_S = 10.0
"""How long :meth:`QemuFirmware.start` waits for QEMU to come up (its QMP socket)."""

STOP_TIMEOUT_S = 3.0
"""How long each stopping step (QMP quit, SIGTERM) waits before the next, harder one."""

BUS_SERIAL_INDEX = 0  # USART1
PC_LINK_SERIAL_INDEX = 2  # USART3
SERIAL_COUNT = 3  # USART1..3 on the stm32f100 SoC


class QemuError(SimFailure):
    """QEMU could not be started, or stopped, as asked."""


@dataclass(frozen=True)
class Endpoint:
    """Where one of the firmware's serial lines goes. Build one with the class methods."""

    kind: str  # "null" | "pty" | "unix-server" | "unix-client" | "chardev"
    path: str | None = None
    spec: str | None = None

    @classmethod
    def null(cls) -> Endpoint:
        """Nothing: the firmware's output is discarded, nothing ever arrives."""
        return cls("null")

    @classmethod
    def pty(cls) -> Endpoint:
        """A pseudo-terminal (/dev/pts/N), opened like a serial port."""
        return cls("pty")

    @classmethod
    def unix_server(cls, path: str | os.PathLike[str] | None = None) -> Endpoint:
        """QEMU listens on a Unix socket (in QEMU's work directory if no path is given);
        connect to it after :meth:`QemuFirmware.start`. Bytes the firmware sends before
        anyone connects are lost."""
        return cls("unix-server", path=None if path is None else os.fspath(path))

    @classmethod
    def unix_client(cls, path: str | os.PathLike[str]) -> Endpoint:
        """QEMU connects to a Unix socket the caller already listens on (and reconnects
        every second if the connection drops)."""
        return cls("unix-client", path=os.fspath(path))

    @classmethod
    def chardev(cls, spec: str) -> Endpoint:
        """Any QEMU ``-chardev`` backend, written without its id, for example
        ``"socket,host=127.0.0.1,port=4000,server=on,wait=off"`` or ``"file,path=bus.log"``."""
        return cls("chardev", spec=spec)


@dataclass(frozen=True)
class QemuPorts:
    """Where to reach the running firmware."""

    pc_link: str
    """The PC link: a pty device path, or the Unix socket path (for pyserial, a socket
    is not a URL it opens; connect with the ``socket`` module)."""
    bus: str | None
    """The bus socket path (or pty path); None for null and other chardevs."""


def find_qemu() -> str:
    """The qemu-system-arm executable, or :class:`QemuError` saying how to install it."""
    chosen = lookup_text("SNAKEBOT_QEMU")  # checked there: found, or SettingError
    if chosen is not None:
        return chosen
    found = shutil.which(QEMU_BINARY)
    if found is None:
        raise QemuError(
            f"{QEMU_BINARY} not found: install QEMU's ARM system emulator (make setup, or "
            "apt-get install qemu-system-arm), or set SNAKEBOT_QEMU to its path"
        )
    return found


class _Qmp:
    """Just enough of QEMU's machine protocol: a JSON object per line over a socket.

    Every command carries an ``id`` that QEMU echoes in its reply, and :meth:`execute`
    returns only the reply with its own id. Taking "the next message that is not an
    event" as the answer, one message left unread (an answer no one waited for, or one
    taken for the greeting) makes every later command get the answer to the one before:
    a fault campaign in CI read its uptime from the table length it had asked for a
    moment earlier and reported a reboot and a lost table that never happened."""

    def __init__(self, path: str, timeout: float) -> None:
        self._sock = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        self._ids = itertools.count(1)
        self._buf = b""
        try:
            self._sock.settimeout(timeout)
            self._sock.connect(path)
            while "QMP" not in self._receive():  # the greeting
                pass
            self.execute("qmp_capabilities")
        except BaseException:
            self.close()  # a half-open session must not linger with an answer in it
            raise

    def _receive(self) -> dict[str, Any]:
        while b"\n" not in self._buf:
            chunk = self._sock.recv(65536)
            if not chunk:
                raise ConnectionError("QEMU closed its QMP socket")
            self._buf += chunk
        line, self._buf = self._buf.split(b"\n", 1)
        return json.loads(line)

    def execute(self, command: str, arguments: dict[str, Any] | None = None) -> Any:
        ident = f"snakebot-{next(self._ids)}"
        message: dict[str, Any] = {"execute": command, "id": ident}
        if arguments:
            message["arguments"] = arguments
        self._sock.sendall(json.dumps(message).encode() + b"\n")
        while True:
            reply = self._receive()
            if reply.get("id") != ident:
                continue  # an event, a greeting, or the answer to another command
            if "error" in reply:
                raise QemuError(f"QEMU refused {command}: {reply['error'].get('desc', reply)}")
            return reply.get("return")

    def send_only(self, command: str) -> None:
        self._sock.sendall(json.dumps({"execute": command}).encode() + b"\n")

    def close(self) -> None:
        with contextlib.suppress(OSError):
            self._sock.close()


_PR_SET_PDEATHSIG = 1
_libc: Any = None


def _die_with_parent() -> None:
    """Runs in the child between fork and exec: SIGKILL when the parent thread dies."""
    if _libc is not None:
        _libc.prctl(_PR_SET_PDEATHSIG, signal.SIGKILL)


def _stop_process(proc: subprocess.Popen[bytes], qmp: _Qmp | None, timeout: float) -> None:
    """Quit politely, then terminate, then kill; always reaps the process."""
    if proc.poll() is None and qmp is not None:
        with contextlib.suppress(OSError, ValueError):
            qmp.send_only("quit")
        with contextlib.suppress(subprocess.TimeoutExpired):
            proc.wait(timeout)
    if qmp is not None:
        qmp.close()
    if proc.poll() is None:
        proc.terminate()
        with contextlib.suppress(subprocess.TimeoutExpired):
            proc.wait(timeout)
    if proc.poll() is None:
        proc.kill()
        proc.wait()


def _close_ptys(ptys: dict[str, tuple[int, int, str]]) -> None:
    """Close both ends of the pseudo-terminals."""
    for master, slave, _path in ptys.values():
        for fd in (master, slave):
            with contextlib.suppress(OSError):
                os.close(fd)
    ptys.clear()


def _finalize(
    proc: subprocess.Popen[bytes],
    qmp_box: list[_Qmp],
    ptys: dict[str, tuple[int, int, str]],
    relays: dict[str, PtyRelay],
    workdir: str | None,
) -> None:
    _stop_process(proc, qmp_box[0] if qmp_box else None, STOP_TIMEOUT_S)
    qmp_box.clear()
    for relay in relays.values():
        relay.stop()
    relays.clear()
    _close_ptys(ptys)
    if workdir is not None:
        shutil.rmtree(workdir, ignore_errors=True)


class QemuFirmware:
    """One QEMU running the firmware image. Not started until :meth:`start` (or ``with``).

    ``image``: a raw flash image loaded at 0x08000000 (default ``build/qemu/flash.bin``;
    ``make firmware`` builds it). ``bus`` (USART1) defaults to :meth:`Endpoint.null`,
    ``pc_link`` (USART3) to :meth:`Endpoint.pty`. ``extra_args`` are appended to QEMU's
    command line (for example ``["-d", "unimp,guest_errors"]``; QEMU's own output goes to
    :attr:`log_path`).
    """

    def __init__(
        self,
        image: str | os.PathLike[str] | None = None,
        *,
        bus: Endpoint | None = None,
        pc_link: Endpoint | None = None,
        extra_args: tuple[str, ...] | list[str] = (),
        die_with_parent: bool = True,
    ) -> None:
        self.image = Path(image) if image is not None else DEFAULT_IMAGE
        self.bus = bus if bus is not None else Endpoint.null()
        self.pc_link = pc_link if pc_link is not None else Endpoint.pty()
        for role, ep in (("bus", self.bus), ("pc_link", self.pc_link)):
            if ep.kind not in ("null", "pty", "unix-server", "unix-client", "chardev"):
                raise QemuError(f"unknown {role} endpoint kind {ep.kind!r}: use Endpoint.*()")
        self.extra_args = list(extra_args)
        self.die_with_parent = die_with_parent and sys.platform.startswith("linux")
        self._proc: subprocess.Popen[bytes] | None = None
        self._started_as: list[str] = []
        """The command QEMU was started with (its pipes' descriptors are gone after)."""
        self._qmp_box: list[_Qmp] = []
        self._workdir: str | None = None
        self._finalizer: weakref.finalize | None = None
        self._ports: QemuPorts | None = None
        self._ptys: dict[str, tuple[int, int, str]] = {}  # label -> (master, slave, path)
        self._pairs: dict[str, tuple[socket.socket, socket.socket]] = {}  # label -> (QEMU's, ours)
        self._relays: dict[str, PtyRelay] = {}

    # -- the command line -------------------------------------------------------------

    def _chardev(self, label: str, ep: Endpoint) -> str:
        assert self._workdir is not None
        if ep.kind == "null":
            return f"null,id={label}"
        if ep.kind == "pty":
            return f"socket,id={label},fd={self._pairs[label][0].fileno()},server=off"
        if ep.kind == "unix-server":
            path = ep.path or os.path.join(self._workdir, f"{label}.sock")
            return f"socket,id={label},path={path},server=on,wait=off"
        if ep.kind == "unix-client":
            return f"socket,id={label},path={ep.path},server=off,reconnect=1"
        return f"{ep.spec},id={label}"

    def command(self) -> list[str]:
        """The QEMU command line :meth:`start` runs (work-directory paths included)."""
        if self._workdir is None:
            raise QemuError("command() needs the work directory: call start() first")
        serials = ["null"] * SERIAL_COUNT
        serials[BUS_SERIAL_INDEX] = "chardev:bus"
        serials[PC_LINK_SERIAL_INDEX] = "chardev:pc"
        cmd = [find_qemu(), "-M", MACHINE, "-nographic", "-monitor", "none"]
        cmd += ["-chardev", self._chardev("bus", self.bus)]
        cmd += ["-chardev", self._chardev("pc", self.pc_link)]
        for s in serials:
            cmd += ["-serial", s]
        cmd += ["-qmp", f"unix:{self._qmp_path},server=on,wait=off"]
        cmd += ["-kernel", str(self.image)]
        return cmd + self.extra_args

    def _open_ptys(self) -> None:
        for label, ep in (("bus", self.bus), ("pc", self.pc_link)):
            if ep.kind == "pty":
                master, slave = os.openpty()
                tty.setraw(slave)
                self._ptys[label] = (master, slave, os.ttyname(slave))
                self._pairs[label] = socket.socketpair(socket.AF_UNIX, socket.SOCK_STREAM)

    def _close_pairs(self) -> None:
        for theirs, ours in self._pairs.values():
            theirs.close()
            if ours.fileno() >= 0 and not any(r.sock is ours for r in self._relays.values()):
                ours.close()
        self._pairs.clear()

    def dropped(self, label: str = "pc") -> int:
        """Bytes the firmware sent on a pty line (``"pc"`` or ``"bus"``) that the terminal
        had no room for, because no client read them."""
        relay = self._relays.get(label)
        return 0 if relay is None else relay.dropped

    @property
    def _qmp_path(self) -> str:
        assert self._workdir is not None
        return os.path.join(self._workdir, "qmp.sock")

    @property
    def log_path(self) -> Path | None:
        """QEMU's stdout and stderr (None before start)."""
        return None if self._workdir is None else Path(self._workdir) / "qemu.log"

    def log(self) -> str:
        """What QEMU printed so far."""
        path = self.log_path
        if path is None or not path.exists():
            return ""
        return path.read_text(errors="replace")

    # -- life cycle -------------------------------------------------------------------

    @property
    def running(self) -> bool:
        return self._proc is not None and self._proc.poll() is None

    @property
    def pid(self) -> int | None:
        return None if self._proc is None else self._proc.pid

    @property
    def ports(self) -> QemuPorts:
        if self._ports is None:
            raise QemuError("QEMU is not running: call start() (or use a with block) first")
        return self._ports

    def start(self, timeout: float = START_TIMEOUT_S) -> QemuPorts:
        """Start QEMU and wait until it answers on QMP; returns where the serial lines are."""
        if self._proc is not None:
            raise QemuError("this QemuFirmware was already started: make a new one")
        if not self.image.is_file():
            raise QemuError(f"firmware image {self.image} not found: build it with `make firmware`")
        self._workdir = make_workdir("qemu")
        if self.die_with_parent:
            global _libc
            if _libc is None:
                _libc = ctypes.CDLL(None, use_errno=True)  # loaded here, never in the child
        try:
            self._open_ptys()
            cmd = self._started_as = self.command()
            with open(self._workdir + "/qemu.log", "wb") as log:
                self._proc = subprocess.Popen(
                    cmd,
                    stdin=subprocess.DEVNULL,
                    stdout=log,
                    stderr=subprocess.STDOUT,
                    preexec_fn=_die_with_parent if self.die_with_parent else None,
                    pass_fds=[theirs.fileno() for theirs, _ours in self._pairs.values()],
                )
        except BaseException:
            self._close_pairs()
            _close_ptys(self._ptys)
            shutil.rmtree(self._workdir, ignore_errors=True)
            raise
        for label, (_theirs, ours) in self._pairs.items():
            # the PC link at its line's rate; the bus's rate is the firmware's to change
            rate = PC_LINK_BAUD / BITS_PER_BYTE if label == "pc" else None
            relay = PtyRelay(ours, self._ptys[label][0], f"snakebot.sim-qemu-{label}-relay", rate)
            self._relays[label] = relay.start()
        self._close_pairs()  # QEMU has its ends; the relays have ours
        self._finalizer = weakref.finalize(
            self, _finalize, self._proc, self._qmp_box, self._ptys, self._relays, self._workdir
        )
        try:
            self._qmp_box.append(self._connect_qmp(timeout))
            self._ports = self._find_ports()
        except BaseException:
            self.stop()
            raise
        return self._ports

    def _connect_qmp(self, timeout: float) -> _Qmp:
        assert self._proc is not None
        deadline = time.monotonic() + timeout
        while True:
            if self._proc.poll() is not None:
                raise QemuError(
                    f"QEMU ({self._started_as[0]}) exited at start-up (status "
                    f"{self._proc.returncode}): {self.log().strip() or 'no output'}; check "
                    f"that it is qemu-system-arm and runs on its own (ask it for its version), "
                    "or point SNAKEBOT_QEMU at one that does; command: "
                    f"{' '.join(self._started_as)}"
                )
            if os.path.exists(self._qmp_path):
                try:
                    return _Qmp(self._qmp_path, max(0.5, deadline - time.monotonic()))
                except (OSError, ValueError):
                    pass
            if time.monotonic() > deadline:
                raise QemuError(
                    f"QEMU did not come up within {timeout:.0f} s: {self.log().strip()}; "
                    "is the machine overloaded? (raise the timeout)"
                )
            time.sleep(0.02)

    def _find_ports(self) -> QemuPorts:
        def where(label: str, ep: Endpoint) -> str | None:
            if ep.kind == "pty":
                return self._ptys[label][2]
            if ep.kind == "unix-server":
                return ep.path or os.path.join(self._workdir or "", f"{label}.sock")
            if ep.kind == "unix-client":
                return ep.path
            return None

        pc = where("pc", self.pc_link)
        if pc is None:
            raise QemuError("the PC link must be a pty or a Unix socket to be reachable")
        return QemuPorts(pc_link=pc, bus=where("bus", self.bus))

    def stop(self, timeout: float = STOP_TIMEOUT_S) -> int | None:
        """Stop QEMU (idempotent); returns its exit status, None if it never started."""
        if self._proc is None:
            return None
        _stop_process(self._proc, self._qmp_box[0] if self._qmp_box else None, timeout)
        if self._finalizer is not None:
            self._finalizer()  # closes the ptys, removes the work directory; runs once
        self._ports = None
        return self._proc.returncode

    def system_reset(self) -> None:
        """Reset the emulated MCU (the boot stub runs again, then the application)."""
        if not self._qmp_box:
            raise QemuError("QEMU is not running: nothing to reset")
        self._qmp_box[0].execute("system_reset")

    def monitor(self, command_line: str) -> str:
        """Run one QEMU monitor command and return its text, for inspecting the machine:
        ``monitor("info registers")``, ``monitor("xp /1wx 0xe000ed08")`` (VTOR)."""
        if not self._qmp_box:
            raise QemuError("QEMU is not running: no monitor to ask")
        return str(
            self._qmp_box[0].execute("human-monitor-command", {"command-line": command_line})
        )

    def read_word(self, address: int) -> int:
        """One 32-bit word of the machine's physical memory (flash, RAM, registers)."""
        return int.from_bytes(self.read(address, 4), "little")

    def read(self, address: int, length: int) -> bytes:
        """``length`` bytes of the machine's physical memory from ``address``, read as the
        whole words around them through the monitor's ``xp``."""
        first = address & ~3
        words = (address + length - first + 3) // 4
        text = self.monitor(f"xp /{words}wx {first:#x}")
        try:
            values = [
                int(v, 16)
                for line in text.splitlines()
                if ":" in line
                for v in line.split(":", 1)[1].split()
            ]
        except ValueError as exc:
            raise QemuError(f"unexpected monitor answer to xp: {text[:200]!r}") from exc
        if len(values) != words:
            raise QemuError(f"the monitor gave {len(values)} words of {words}: {text[:200]!r}")
        raw = b"".join(v.to_bytes(4, "little") for v in values)
        return raw[address - first : address - first + length]

    def __enter__(self) -> QemuFirmware:
        if self._proc is None:
            self.start()
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.stop()


def main(argv: list[str] | None = None) -> int:
    """``python -m snakebot.sim.qemu``: run the firmware under QEMU until Ctrl-C, printing
    where its serial lines are (for poking at it by hand)."""
    import argparse

    parser = argparse.ArgumentParser(
        prog="python -m snakebot.sim.qemu",
        description="Run the qemu board firmware image under qemu-system-arm. The PC link "
        "(USART3) is a pseudo-terminal: open it at 57600 baud like the CM-530's USB port.",
    )
    parser.add_argument("--image", help=f"flash image (default {DEFAULT_IMAGE})")
    parser.add_argument(
        "--bus",
        metavar="SOCKET",
        help="Unix socket of a listening emulated servo bus to connect USART1 to "
        "(default: nothing on the bus)",
    )
    args = parser.parse_args(argv)
    bus = Endpoint.unix_client(args.bus) if args.bus else Endpoint.null()
    try:
        with QemuFirmware(args.image, bus=bus) as fw:
            print(f"PC link: {fw.ports.pc_link}  (QEMU pid {fw.pid}; Ctrl-C stops it)")
            while fw.running:
                time.sleep(0.5)
            print(f"QEMU exited: {fw.log().strip()}")
    except KeyboardInterrupt:
        pass
    except QemuError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
