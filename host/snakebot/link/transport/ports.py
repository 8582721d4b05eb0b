"""Opening a serial port by device path or pyserial URL, with errors a person can act on.

Every snakebot command that talks to hardware opens its port here, so a missing
adapter, a permission problem or a typo in a URL reads the same everywhere. Anything
``serial.serial_for_url`` accepts works: ``/dev/ttyUSB0``, ``COM3``, ``loop://``,
``socket://host:port``, ``spy://...``, and schemes that other packages register (the
emulator adds ``sim://`` through :func:`register_handler_package`).
"""

from __future__ import annotations

import errno
import os
import re
import stat
import sys
import tempfile
from pathlib import Path

import serial

from snakebot.link.transport.errors import PortError
from snakebot.link.transport.timing import DEFAULT_BAUDRATE

if sys.platform.startswith("linux"):
    _PERMISSION_FIX = (
        "add your user to the dialout group (sudo usermod -aG dialout $USER, then log out "
        "and back in) or check the device's permissions with ls -l"
    )
else:
    _PERMISSION_FIX = "check that your user may open the device"


def register_handler_package(package: str) -> None:
    """Let ``serial_for_url`` find ``<package>.protocol_<scheme>`` modules (idempotent)."""
    if package not in serial.protocol_handler_packages:
        serial.protocol_handler_packages.append(package)


EMULATOR_HANDLER_PACKAGE = "snakebot.sim.urlhandler"
"""Where the emulator's ``sim://`` handler lives. pyserial imports it only when a sim://
URL is opened, so every ``--port`` reaches the emulated robot at no start-up cost."""

register_handler_package(EMULATOR_HANDLER_PACKAGE)


def _explain(url: str, exc: BaseException) -> str:
    code = getattr(exc, "errno", None)
    text = str(exc)
    if code == errno.ENOENT or "No such file" in text:
        return (
            f"serial port {url} does not exist: check that the adapter is plugged in and "
            "use the right name (on Linux, ls /dev/ttyUSB* /dev/ttyACM*; on Windows, COMn)"
        )
    if code in (errno.EACCES, errno.EPERM) or "Permission denied" in text:
        return f"no permission to open serial port {url}: {_PERMISSION_FIX}"
    if code == errno.EBUSY or "busy" in text.lower() or "exclusively lock" in text:
        return (
            f"serial port {url} is in use by another program: close it (a terminal, "
            "another snakebot, the ROBOTIS tools) and try again"
        )
    if "Connection refused" in text or code == errno.ECONNREFUSED:
        return f"nothing is listening at {url}: start the server first or check host and port"
    return f"could not open serial port {url}: {text}"


LOCK_DIR_NAME = "snakebot-ports"
"""Directory (in the temporary directory, one per user) of the lock files that name each
port's holder; the device's own ``flock`` keeps other users' programs out."""


def _lock_path(device: str) -> Path:
    # The real path, so a symlink (sim bus --link /tmp/ttyDXL) and its target share a lock.
    name = os.path.realpath(device).strip("/").replace("/", "_") or "root"
    return Path(tempfile.gettempdir()) / f"{LOCK_DIR_NAME}-{os.getuid()}" / f"{name}.lock"


class PortLock:
    """An advisory lock on a device, held for as long as the port is open: a lock file
    locked with ``flock`` (released by the kernel when the process ends, however it ends)
    that names the holder, so a second opener can say who has the port."""

    def __init__(self, device: str) -> None:
        import fcntl  # POSIX only; Windows opens a COM port exclusively by itself

        self.path = _lock_path(device)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._fd = os.open(self.path, os.O_RDWR | os.O_CREAT, 0o666)
        try:
            fcntl.flock(self._fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            holder = os.pread(self._fd, 512, 0).decode(errors="replace").strip()
            os.close(self._fd)
            raise PortError(
                device,
                f"serial port {device} is in use by {holder or 'another snakebot'}: stop "
                "that program first (two programs on one port read each other's replies)",
            ) from None
        holder = f"pid {os.getpid()} ({' '.join(Path(a).name for a in sys.argv[:3])})"
        os.ftruncate(self._fd, 0)
        os.pwrite(self._fd, holder.encode(), 0)

    def release(self) -> None:
        if self._fd >= 0:
            os.ftruncate(self._fd, 0)
            os.close(self._fd)  # closing the descriptor releases the flock
            self._fd = -1


def _is_device(url: str) -> bool:
    return "://" not in url


LINUX_PTY_SLAVE_MAJORS = range(136, 144)
"""Character-device major numbers of Unix98 pseudo-terminal slaves (/dev/pts/N) in Linux's
list of allocated devices (Documentation/admin-guide/devices.txt)."""

_MACOS_PTY = re.compile(r"/dev/ttys\d+")


def is_pseudo_terminal(url: str) -> bool:
    """Whether ``url`` is a pseudo-terminal (by way of any symlink): the device at its far
    end is then a program on this host, such as the emulated controller, not a UART."""
    if not _is_device(url):
        return False
    try:
        mode = os.stat(url)
    except OSError:
        return False
    if not stat.S_ISCHR(mode.st_mode):
        return False
    if sys.platform.startswith("linux"):
        return os.major(mode.st_rdev) in LINUX_PTY_SLAVE_MAJORS
    return _MACOS_PTY.fullmatch(os.path.realpath(url)) is not None


def open_port(
    url: str, baudrate: int = DEFAULT_BAUDRATE, timeout: float | None = None
) -> serial.SerialBase:
    """Open ``url`` (device path or pyserial URL) at ``baudrate``, 8N1, with read ``timeout``
    in seconds (None blocks). Raises :class:`PortError` naming the port and the fix.

    A device (a path, not a URL) is opened exclusively: a second opener, in this process
    or another, gets a PortError naming the first (snakebot's) or saying the port is busy
    (another program's ``flock``, as pyserial's ``exclusive`` takes it)."""
    if not url:
        raise PortError(url, "no serial port given: pass a device (/dev/ttyUSB0) or a URL")
    posix = os.name == "posix"
    lock = PortLock(url) if posix and _is_device(url) and os.path.exists(url) else None
    try:
        port = _open(url, baudrate, timeout, exclusive=lock is not None)
    except BaseException:
        if lock is not None:
            lock.release()
        raise
    if lock is not None:
        close = port.close

        def close_and_unlock() -> None:
            try:
                close()
            finally:
                lock.release()

        port.close = close_and_unlock  # type: ignore[method-assign]
    return port


def _open(url: str, baudrate: int, timeout: float | None, exclusive: bool) -> serial.SerialBase:
    extra = {"exclusive": True} if exclusive else {}
    try:
        return serial.serial_for_url(url, baudrate=baudrate, timeout=timeout, **extra)
    except ValueError as exc:
        if "protocol" in str(exc) and "://" in url:
            scheme = url.split("://", 1)[0]
            raise PortError(
                url,
                f"unknown port scheme {scheme}:// in {url}: use a device path or one of "
                "loop://, socket://host:port, spy://, rfc2217://, or sim:// once the "
                "emulator is installed",
            ) from exc
        raise PortError(url, f"cannot use serial port {url}: {exc}") from exc
    except (serial.SerialException, OSError) as exc:
        raise PortError(url, _explain(url, exc)) from exc
