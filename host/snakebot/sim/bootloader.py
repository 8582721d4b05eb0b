"""An emulated ROBOTIS CM-530 bootloader, served on a real pseudo-terminal.

It behaves as the public descriptions of the real one say (docs/hardware.md, "Uploading
firmware through the ROBOTIS bootloader"), so `snakebot flash` can be tested end to end
without a board:

* After a reset it ignores everything but ``#``. The first ``#`` gets a banner and a
  prompt; further ``#`` (the host keeps sending them for a moment) are ignored.
* At the prompt it reads command lines (ended by CR or LF; echoed as typed, like a
  terminal; case does not matter):

  ========  ===============================================================
  ``L``     load: answers ``Ready..``, then takes raw image bytes
  ``GO``    starts the application at 0x08003000 (answers ``Go 0x08003000``)
  ``G A``   starts code at hex address A
  ``APP``   the next reset boots the application
  ``SYS``   the next reset stays in the bootloader
  ``help``  lists the commands
  ========  ===============================================================

* An image has no length field and no framing, so the end of an image can only be told
  by silence on the line: once :attr:`Bootloader.silence_s` passes with no new byte, it
  stores the image and reports ``Size: N`` and ``Checksum: XX``. XX is two hex digits,
  the low byte of the sum of *every* byte it received, including the checksum byte that
  RoboPlus Terminal appends (the real bootloader's exact sum is not confirmed; see
  docs/hardware.md). With ``sum_excludes_last`` it sums all but the last byte instead,
  the other reading of the same descriptions. How the sum is printed is not confirmed
  either: ``checksum_format`` picks one of :data:`CHECKSUM_FORMATS` (8, 16 or 32 bits, hex
  or decimal, and one the host cannot read).
* It keeps every image it received (:attr:`Bootloader.images`), so a test can compare
  the stored bytes with the file, byte for byte.

Faults for tests (:class:`BootloaderFaults`): ``mute`` never answers ``#``; ``no_ready``
never answers the load command; ``corrupt`` flips one bit of the stored image, so the
reported checksum is wrong; ``drop_every`` loses every Nth image byte on the way in (a
line that drops bytes); ``reset_after`` resets the board once that many image bytes have
arrived (a power glitch, or MODE pressed, during the transfer).

The line runs at 57600 8N1. On the pseudo-terminal a client that set another baud rate
is not understood (its bytes are dropped, as a UART at the wrong rate would garble them),
and, with ``pace`` on (the default), bytes are taken from the client no faster than
57600 baud carries them, so the client's writes back up as on a real serial link.
"""

from __future__ import annotations

import errno
import fcntl
import os
import select
import socket
import struct
import tempfile
import termios
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from snakebot.errors import InputError
from snakebot.facts.boards import APP_BASE, PC_LINK_BAUD
from snakebot.facts.memory import FLASH_BASE
from snakebot.sim.transports.base import RawPty, Server
from snakebot.sim.transports.pty import tty_baudrate

"""Where the STM32's flash starts (the bootloader's own first byte)."""

APP_AREA = 500 * 1024
"""The application area the bootloader writes: 0x08003000 up to the end of the 512 KB flash."""

DEFAULT_SILENCE_S = 0.1
"""Silence after the last image byte that ends the image. The real bootloader's value is
not documented; the host must simply never pause this long in the middle of an image."""

HELD_S = 0.02
"""How late past its deadline the served bootloader's thread must wake to count as held
up by the host (:meth:`Bootloader.held`); the kernel wakes sleepers well within it."""

LINE_MAX = 64
"""Longest command line kept (the rest is dropped)."""

IDLE_WAKE_S = 0.05
"""Longest the server thread sleeps when nothing is due."""

HANGUP_S = 3.0
"""After an image the board could not start: how long the PC side of the line must stay
closed before the client counts as gone. The flasher closes the port after GO and opens it
again at once to check the new firmware; that gap is far shorter, even on a machine so
loaded that the flasher is descheduled for a second."""

PACE_BLOCK = 32
"""With wire pacing, bytes are taken from the client in blocks of about this many (a
5.6 ms slice of the 57600 baud line), never faster than the line could carry them."""

BANNER = (
    "\r\n\r\nROBOTIS CM-530 boot loader (snakebot.sim emulation)\r\n"
    f"Application area 0x{APP_BASE:08X}-0x{APP_BASE + APP_AREA - 1:08X} ({APP_AREA // 1024} KB)"
    "\r\nType help for the commands.\r\n"
)
PROMPT = "\r\n[CM-530]> "
HELP = (
    "\r\nCommands:\r\n"
    "  L        load: send the raw image after Ready..\r\n"
    "  GO       start the application at 0x08003000\r\n"
    "  G ADDR   start code at hex address ADDR\r\n"
    "  APP      boot the application after reset\r\n"
    "  SYS      stay in the boot loader after reset\r\n"
    "  help     this list\r\n"
)


CHECKSUM_FORMATS: dict[str, tuple[str, int]] = {
    "hex8": ("Checksum: {:02X}", 8),
    "hex16": ("Checksum: {:04X}", 16),
    "hex32": ("Checksum: 0x{:08X}", 32),
    "hex32-lower": ("Checksum:{:x}", 32),
    "dec8": ("Checksum: {:d}", 8),
    "dec16": ("Checksum : {:d}", 16),
    "dec32": ("CHECKSUM {:d}", 32),
    "unknown": ("Checksum: OK", 8),
}
"""Ways the report may be printed: name -> (line template, sum width in bits). "unknown"
prints no number at all."""


@dataclass(frozen=True)
class BootloaderFaults:
    """What to get wrong, for tests of the host's error paths."""

    mute: bool = False  # never answer '#'
    no_ready: bool = False  # never answer the load command
    corrupt: bool = False  # flip one bit of the stored image (middle byte)
    drop_every: int = 0  # lose every Nth image byte (0: none)
    flash_corrupt: bool = False  # report the sum of what arrived, but store one bit wrong
    reset_after: int | None = None  # reset once this many image bytes have arrived


@dataclass
class Bootloader:
    """The bootloader's state machine: bytes in, bytes out, on a clock you pass in.

    ``hash_window_s``: how long after a reset it listens for ``#`` before starting the
    application (None: until one comes). ``boot_mode``: "app" or "sys", as set by the APP
    and SYS commands.
    """

    faults: BootloaderFaults = field(default_factory=BootloaderFaults)
    silence_s: float = DEFAULT_SILENCE_S
    sum_excludes_last: bool = False
    checksum_format: str = "hex8"
    hash_window_s: float | None = None
    capacity: int = APP_AREA
    boot_mode: str = "app"
    state: str = "app"  # "app" (running the application), "wait_hash", "prompt", "receive"
    images: list[bytes] = field(default_factory=list)
    started: list[int] = field(default_factory=list)  # addresses jumped to (GO, G)
    commands: list[str] = field(default_factory=list)  # every command line, for tests
    _line: bytearray = field(default_factory=bytearray)
    _rx: bytearray = field(default_factory=bytearray)
    _overflow: int = 0
    _arrived: int = 0  # image bytes that reached the line, dropped ones included
    _last_rx: float = 0.0
    _window_end: float | None = None

    # -- what tests look at ---------------------------------------------------------------

    @property
    def image(self) -> bytes | None:
        """The last image stored (as received, trailing checksum byte included)."""
        return self.images[-1] if self.images else None

    @staticmethod
    def reported_sum(data: bytes, excludes_last: bool = False, bits: int = 8) -> int:
        """The sum this bootloader reports for ``data``, ``bits`` wide."""
        return sum(data[:-1] if excludes_last else data) % (1 << bits)

    def report_line(self, data: bytes) -> str:
        """The ``Checksum`` line for a stored image, in :attr:`checksum_format`."""
        template, bits = CHECKSUM_FORMATS[self.checksum_format]
        return template.format(self.reported_sum(data, self.sum_excludes_last, bits))

    # -- events ---------------------------------------------------------------------------

    def reset(self, now: float) -> bytes:
        """The board was reset (RESET pressed, or power on)."""
        self._line.clear()
        self._rx.clear()
        if self.boot_mode == "sys":
            self.state = "prompt"
            return (BANNER + PROMPT).encode()
        self.state = "wait_hash"
        self._window_end = None if self.hash_window_s is None else now + self.hash_window_s
        return b""

    def feed(self, data: bytes, now: float) -> bytes:
        """Bytes from the host arrived at ``now``; returns what the bootloader sends back.

        Bytes that arrive do not end an image by the silence before them: had the line
        been silent that long, :meth:`poll` would have ended it then. Coming here late
        means the emulator was held up while they waited in the terminal (a busy host),
        and a real line carried them without a pause."""
        out = bytearray(self.poll(now, line_busy=True))
        for i, byte in enumerate(data):
            if self.state == "receive":
                out += self._receive(data[i:], now)
                break
            out += self._byte(byte, now)
        return bytes(out)

    def poll(self, now: float, line_busy: bool = False) -> bytes:
        """Let time pass: ends an image after the silence (unless ``line_busy``: bytes are
        waiting to be read, so the line was not silent), closes the '#' window."""
        if self.state == "receive" and (self._rx or self._overflow) and not line_busy:
            if now - self._last_rx >= self.silence_s:
                return self._store()
        if self.state == "wait_hash" and self._window_end is not None and now >= self._window_end:
            self.state = "app"
        return b""

    def held(self, seconds: float) -> None:
        """The emulator was held up for ``seconds`` (its thread woke that late, the host
        busy with other work): a silence it did not watch is not one the line had, as the
        client, held up alike, could not write meanwhile. The image's silence counts on
        from the end of the hold."""
        if self.state == "receive":
            self._last_rx += seconds

    def next_deadline(self) -> float | None:
        """When :meth:`poll` next has something to do (None: only on input)."""
        if self.state == "receive" and (self._rx or self._overflow):
            return self._last_rx + self.silence_s
        if self.state == "wait_hash":
            return self._window_end
        return None

    # -- states ---------------------------------------------------------------------------

    def _byte(self, byte: int, now: float) -> bytes:
        if self.state == "app":
            return b""
        if self.state == "wait_hash":
            if byte == ord("#") and not self.faults.mute:
                self.state = "prompt"
                return (BANNER + PROMPT).encode()
            return b""
        # prompt: a command line, echoed as typed
        if byte == ord("#") and not self._line:
            return b""  # the host's leftover '#'
        if byte in (0x0D, 0x0A):
            line = self._line.decode("latin-1").strip()
            self._line.clear()
            return self._command(line, now)
        if byte in (0x08, 0x7F):
            if self._line:
                self._line.pop()
                return b"\x08 \x08"
            return b""
        if 0x20 <= byte < 0x7F and len(self._line) < LINE_MAX:
            self._line.append(byte)
            return bytes([byte])
        return b""

    def _command(self, line: str, now: float) -> bytes:
        if not line:
            return PROMPT.encode()
        self.commands.append(line)
        word, _, arg = line.partition(" ")
        word = word.upper()
        if word in ("L", "LOAD"):
            if self.faults.no_ready:
                return b""
            self.state = "receive"
            self._rx.clear()
            self._overflow = 0
            self._arrived = 0
            self._last_rx = now
            return b"\r\nReady..\r\n"
        if word == "GO" and not arg:
            return self._jump(APP_BASE)
        if word == "G":
            try:
                address = int(arg.strip(), 16)
            except ValueError:
                return f"\r\nG needs a hex address, e.g. G 8003000{PROMPT}".encode()
            return self._jump(address)
        if word == "APP":
            self.boot_mode = "app"
            return f"\r\nBoot mode: application after reset{PROMPT}".encode()
        if word == "SYS":
            self.boot_mode = "sys"
            return f"\r\nBoot mode: boot loader after reset{PROMPT}".encode()
        if word in ("HELP", "?"):
            return (HELP + PROMPT).encode()
        return f"\r\nUnknown command: {line} (type help){PROMPT}".encode()

    def _jump(self, address: int) -> bytes:
        self.started.append(address)
        self.state = "app"
        return f"\r\nGo 0x{address:08X}\r\n".encode()

    def _receive(self, data: bytes, now: float) -> bytes:
        faults = self.faults
        first = self._arrived
        self._arrived += len(data)
        if faults.reset_after is not None and self._arrived >= faults.reset_after:
            return self.reset(now)  # the rest of the image meets a restarted board
        if faults.drop_every:
            data = bytes(b for n, b in enumerate(data, first + 1) if n % faults.drop_every)
        room = self.capacity + 1 - len(self._rx)  # one extra: the optional checksum byte
        self._rx += data[:room]
        self._overflow += max(0, len(data) - room)
        self._last_rx = now
        return b""

    def _store(self) -> bytes:
        self.state = "prompt"
        if self._overflow:
            size = len(self._rx) + self._overflow
            self._rx.clear()
            self._overflow = 0
            return (
                f"\r\nError: {size} bytes is more than the {self.capacity} byte application "
                f"area; nothing stored{PROMPT}"
            ).encode()
        data = bytearray(self._rx)
        self._rx.clear()
        if self.faults.corrupt:
            data[len(data) // 2] ^= 0x01
        report = self.report_line(data)
        if self.faults.flash_corrupt:
            data[-2] ^= 0x01  # the image's last byte (the last is the checksum byte)
        self.images.append(bytes(data))
        return f"\r\nSize: {len(data)}\r\n{report}\r\n{PROMPT}".encode()


Handover = Callable[[bytes], socket.socket]
"""Starts the application the bootloader stored (its bytes as received) and returns a
connected socket to its PC link; raises :class:`~snakebot.errors.InputError` for an image
the board could not start (the message says why and how to fix it)."""


class QemuHandover:
    """A :data:`Handover` to QEMU: the qemu board's boot stub, then the stored image at the
    application base, with the PC link on a Unix socket. So `snakebot flash` can be tested
    end to end: the firmware it sent is the firmware that then answers."""

    def __init__(self) -> None:
        self.firmware = None
        self._dir: tempfile.TemporaryDirectory[str] | None = None

    def __call__(self, image: bytes) -> socket.socket:
        from snakebot.firmware import image as firmware_image
        from snakebot.sim.qemu import Endpoint, QemuFirmware

        stub = firmware_image("qemu", "stub.bin").read_bytes()
        self._dir = tempfile.TemporaryDirectory(prefix="snakebot-handover-")
        flash = Path(self._dir.name) / "flash.bin"
        flash.write_bytes(stub + b"\xff" * (APP_BASE - FLASH_BASE - len(stub)) + image)
        self.firmware = QemuFirmware(flash, pc_link=Endpoint.unix_server())
        ports = self.firmware.start()
        link = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        link.connect(ports.pc_link)
        link.setblocking(False)
        return link

    def close(self) -> None:
        if self.firmware is not None:
            self.firmware.stop()
            self.firmware = None
        if self._dir is not None:
            self._dir.cleanup()
            self._dir = None


class BootloaderPty(Server):
    """Serves a :class:`Bootloader` on a new pseudo-terminal from a background thread.

        with BootloaderPty(Bootloader()) as server:
            print(server.device)   # give this to `snakebot flash --port`

    ``reset_after_s``: the board is "running its application" (silent) until this many
    seconds after :meth:`start`, then resets, as when a user presses MODE; None resets at
    once. ``pace``: take the client's bytes at the line's speed (False: as fast as they
    come, for quick tests). ``link``: also make a symlink at this path to the device.
    ``on_go``: after GO, start the stored image with this :data:`Handover` and relay the
    line to it from then on (until a reset).

    An image ``on_go`` refuses (one the board could not start) leaves the board as a CM-530
    whose application does not run: :attr:`not_started` holds the refusal, the line stays,
    and what comes on it is read and dropped, nothing answers (a reset is not modelled
    then). The server ends by itself once the client has let go of the line (the device
    closed for :data:`HANGUP_S`).
    """

    def __init__(
        self,
        bootloader: Bootloader | None = None,
        *,
        reset_after_s: float | None = None,
        pace: bool = True,
        link: str | os.PathLike[str] | None = None,
        on_go: Handover | None = None,
    ) -> None:
        self.bootloader = bootloader or Bootloader()
        self.on_go = on_go
        self._app: socket.socket | None = None
        self._handed = 0  # jumps already handed over
        self.reset_after_s = reset_after_s
        self.pace = pace
        self._pty = RawPty(link)
        self.link = self._pty.link
        self.device = ""
        self.dropped = 0  # bytes received at a wrong baud rate
        self.error: BaseException | None = None
        self.not_started: InputError | None = None  # why the board could not start the image
        self._wake_r = self._wake_w = -1
        self._thread: threading.Thread | None = None
        self._lock = threading.Lock()
        self._reset_at: float | None = None
        self._pending_reset = False

    @property
    def lock(self) -> threading.Lock:
        """Hold this while looking at the bootloader from another thread."""
        return self._lock

    @property
    def running(self) -> bool:
        return self._thread is not None and self._thread.is_alive()

    def start(self) -> BootloaderPty:
        self.device = self._pty.open()
        self._wake_r, self._wake_w = os.pipe()
        now = time.monotonic()
        if self.reset_after_s is None:
            self._send(self.bootloader.reset(now))
        else:
            self._reset_at = now + self.reset_after_s
        self._thread = threading.Thread(
            target=self._guarded, name=f"snakebot.sim-bootloader {self.device}", daemon=True
        )
        self._thread.start()
        return self

    def press_reset(self) -> None:
        """Reset the emulated board now, as pressing MODE does (from any thread)."""
        with self._lock:
            self._pending_reset = True
        self._wake()

    def _wake(self) -> None:
        if self._wake_w >= 0:
            try:
                os.write(self._wake_w, b"r")
            except OSError:
                pass

    def _send(self, data: bytes) -> None:
        view = memoryview(data)
        while view:
            try:
                view = view[os.write(self._pty.master, view) :]
            except BlockingIOError:
                return  # the client is not reading: the rest is lost, as on a real line
            except OSError as exc:
                if exc.errno in (errno.EIO, errno.EBADF):
                    return
                raise

    def _guarded(self) -> None:
        try:
            self._run()
        except BaseException as exc:  # kept for close() and tests to look at
            self.error = exc

    def _run(self) -> None:
        boot = self.bootloader
        byte_s = 10 / PC_LINK_BAUD
        credit = float(PACE_BLOCK)  # bytes the line could have carried by now
        credit_t = time.monotonic()
        while True:
            now = time.monotonic()
            waiting = _bytes_waiting(self._pty.master)
            with self._lock:
                self._reset_if_due(now)
                self._send(boot.poll(now, line_busy=waiting))
                due = [t for t in (boot.next_deadline(), self._reset_at) if t is not None]
            wait = min([IDLE_WAKE_S] + [max(0.0, t - now) for t in due])
            watch = [self._wake_r]
            if self.pace:
                credit = min(PACE_BLOCK, credit + (now - credit_t) / byte_s)
                credit_t = now
                if credit >= PACE_BLOCK:
                    watch.append(self._pty.master)
                else:
                    wait = min(wait, (PACE_BLOCK - credit) * byte_s)
            else:
                watch.append(self._pty.master)
            if self._app is not None:
                watch.append(self._app)
            try:
                ready, _, _ = select.select(watch, [], [], wait)
            except (OSError, ValueError):
                return
            late = time.monotonic() - (now + wait)
            if not ready and late > HELD_S:
                with self._lock:
                    boot.held(late)
            if self._wake_r in ready and b"x" in os.read(self._wake_r, 64):
                return
            if self._app is not None and self._app in ready:
                self._relay_from_app()
            if self._pty.master not in ready:
                continue
            try:
                data = os.read(self._pty.master, int(credit) if self.pace else 4096)
            except BlockingIOError:
                continue
            except OSError as exc:
                if exc.errno in (errno.EIO, errno.EBADF):
                    continue  # no client has the device open right now
                raise
            credit -= len(data)
            baud = tty_baudrate(self._pty.slave)
            with self._lock:
                if baud is not None and baud != PC_LINK_BAUD:
                    self.dropped += len(data)
                    continue
                # a reset pressed before these bytes came acts before them
                arrived = time.monotonic()
                self._reset_if_due(arrived)
                if self._app is not None:
                    self._app.sendall(data)
                    continue
                self._send(boot.feed(data, arrived))
                jumped = self.on_go is not None and len(boot.started) > self._handed
                self._handed = len(boot.started)
                image = boot.image
            if jumped and image is not None and not self._hand_over(image):
                self._drop_until_let_go()
                return

    def _hand_over(self, image: bytes) -> bool:
        """Start ``image`` with ``on_go`` and relay the line to it; False when the board
        could not start it (:attr:`not_started` says why)."""
        assert self.on_go is not None
        try:
            self._app = self.on_go(image)
        except InputError as exc:
            self.not_started = exc
            return False
        return True

    def _drop_until_let_go(self) -> None:
        """The board's application does not run: read and drop what comes, answer nothing,
        until the client has closed the device for :data:`HANGUP_S` (or :meth:`close`)."""
        self._pty.release_slave()  # so the master sees the client let go
        gone_since: float | None = None
        while True:
            watch = [self._wake_r] if gone_since is not None else [self._wake_r, self._pty.master]
            try:
                ready, _, _ = select.select(watch, [], [], IDLE_WAKE_S)
            except (OSError, ValueError):
                return
            if self._wake_r in ready and b"x" in os.read(self._wake_r, 64):
                return
            now = time.monotonic()
            if _read_and_drop(self._pty.master):
                gone_since = None
            elif gone_since is None:
                gone_since = now
            elif now - gone_since >= HANGUP_S:
                return

    def _reset_if_due(self, now: float) -> None:
        """Apply a reset pressed (:meth:`press_reset`) or scheduled; under the lock."""
        if self._pending_reset or (self._reset_at is not None and now >= self._reset_at):
            self._pending_reset = False
            self._reset_at = None
            self._stop_app()
            self._send(self.bootloader.reset(now))

    def _relay_from_app(self) -> None:
        assert self._app is not None
        try:
            data = self._app.recv(4096)
        except BlockingIOError:
            return
        except OSError:
            data = b""
        if data:
            self._send(data)
        else:
            self._stop_app()  # the application went away

    def _stop_app(self) -> None:
        if self._app is not None:
            self._app.close()
            self._app = None

    def close(self) -> None:
        """Stop serving and remove the device (and the link)."""
        if self._thread is not None:
            if self._wake_w >= 0:
                os.write(self._wake_w, b"x")
            self._thread.join(5.0)
            self._thread = None
        self._stop_app()
        self._pty.close()
        for fd in (self._wake_r, self._wake_w):
            if fd >= 0:
                os.close(fd)
        self._wake_r = self._wake_w = -1


def _read_and_drop(fd: int) -> bool:
    """Read what waits on the pty master ``fd`` and drop it; False when no client has the
    device open (the read fails with EIO, or returns nothing)."""
    try:
        while os.read(fd, 4096):
            pass
    except BlockingIOError:
        return True
    except OSError as exc:
        if exc.errno in (errno.EIO, errno.EBADF):
            return False
        raise
    return False


def _bytes_waiting(fd: int) -> bool:
    """Whether bytes from the client wait in the terminal, unread (FIONREAD)."""
    try:
        return struct.unpack("i", fcntl.ioctl(fd, termios.FIONREAD, b"\0\0\0\0"))[0] > 0
    except OSError:
        return False
