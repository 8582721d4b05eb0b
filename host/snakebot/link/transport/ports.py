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
from urllib.parse import urlsplit

import serial

from snakebot.link.transport.errors import PortError
from snakebot.link.transport.portlock import PortLock
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


def _is_device(url: str) -> bool:
    return "://" not in url


DEVICE_SCHEMES = ("spy", "alt")
"""pyserial URL schemes whose path is a local device (``spy:///dev/ttyUSB0``, a logging
wrapper; ``alt:///dev/ttyUSB0?class=...``, another implementation): they lock it as a
device path does, so a wrapper cannot get round the one-program-per-port lock."""


def device_of(url: str) -> str | None:
    """The local device ``url`` opens (itself for a path, the path inside a ``spy://``
    or ``alt://`` URL), or None (a network or emulated port)."""
    if _is_device(url):
        return url
    parts = urlsplit(url)
    if parts.scheme.lower() in DEVICE_SCHEMES:
        return (parts.netloc + parts.path) or None
    return None


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

    A device (a path, or a URL of :data:`DEVICE_SCHEMES` that wraps one) is opened
    exclusively: a second opener, in this process
    or another, gets a PortError naming the first (snakebot's) or saying the port is busy
    (another program's ``flock``, as pyserial's ``exclusive`` takes it)."""
    if not url:
        raise PortError(url, "no serial port given: pass a device (/dev/ttyUSB0) or a URL")
    posix = os.name == "posix"
    device = device_of(url) if posix else None
    lock = PortLock(device) if device is not None and os.path.exists(device) else None
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
