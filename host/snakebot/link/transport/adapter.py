"""What the adapter between the host and the bus adds to a reply's time: its latency.

A USB-serial adapter holds the bytes it receives until its buffer fills or its latency
timer runs out, so a reply can reach the host that much after its last byte was on the
wire. How long depends on the adapter, not on snakebot:

* an FTDI adapter (USB2Dynamixel, most USB-serial cables) on Linux shows its latency
  timer in sysfs, ``/sys/bus/usb-serial/devices/<tty>/latency_timer``, in milliseconds:
  16 by default, 1 once lowered (what the Dynamixel tools advise); writing it needs
  root, or a udev rule (:data:`UDEV_RULE`);
* a pseudo-terminal (the emulator's ``snakebot sim bus --pty``) and the in-process
  emulator (``sim://``, whose port says so with an ``adapter_latency_s`` attribute) hold
  nothing: zero;
* anything else (another driver, another system, a network link) is unknown, and the
  caller falls back to the configured allowance (``SNAKEBOT_LATENCY_MS``).
"""

from __future__ import annotations

import os
from pathlib import Path

import serial

from snakebot.link.transport.errors import PortError
from snakebot.link.transport.ports import is_pseudo_terminal

SYSFS_USB_SERIAL = Path("/sys/bus/usb-serial/devices")
"""Where Linux lists USB-serial ports, each with its driver's attributes."""

LOWERED_LATENCY_MS = 1
"""The latency timer the Dynamixel tools advise (the least an FTDI chip accepts)."""

UDEV_RULE = 'ACTION=="add", SUBSYSTEM=="usb-serial", DRIVER=="ftdi_sio", ATTR{latency_timer}="1"'
"""A udev rule (e.g. in ``/etc/udev/rules.d/99-ftdi-latency.rules``) that lowers every
FTDI adapter's latency timer as it is plugged in."""


def device_of(port: serial.SerialBase) -> str | None:
    """The device path of an open port, or None for a URL's port (``sim://``, sockets)."""
    name = getattr(port, "port", None)
    if not isinstance(name, str) or "://" in name:
        return None
    return name


def latency_timer_path(device: str, sysfs: Path = SYSFS_USB_SERIAL) -> Path:
    """The sysfs file holding ``device``'s latency timer (whether or not it exists)."""
    return sysfs / Path(os.path.realpath(device)).name / "latency_timer"


def latency_timer_ms(device: str, sysfs: Path = SYSFS_USB_SERIAL) -> int | None:
    """``device``'s FTDI latency timer in milliseconds, None where it has none to show
    (a URL, another kind of device, another system)."""
    if "://" in device:
        return None
    try:
        return int(latency_timer_path(device, sysfs).read_text().strip())
    except (OSError, ValueError):
        return None


def on_pseudo_terminal(port: serial.SerialBase) -> bool:
    """Whether ``port`` is a pseudo-terminal: its far end is then a program on this host,
    which a busy host may deschedule for far longer than a UART ever stalls."""
    device = device_of(port)
    return device is not None and is_pseudo_terminal(device)


def latency_s(port: serial.SerialBase) -> float | None:
    """How long the adapter behind ``port`` may hold a reply, in seconds; None when it
    cannot be told (then the configured allowance applies)."""
    declared = getattr(port, "adapter_latency_s", None)
    if isinstance(declared, (int, float)):
        return float(declared)
    device = device_of(port)
    if device is None:
        return None
    if is_pseudo_terminal(device):  # a program's, through the kernel: nothing held
        return 0.0
    timer = latency_timer_ms(device)
    return None if timer is None else timer / 1e3


def lowering_fix(device: str, sysfs: Path = SYSFS_USB_SERIAL) -> str:
    """How to lower ``device``'s latency timer to 1 ms, and the permission that needs."""
    path = latency_timer_path(device, sysfs)
    return (
        f"lower it to {LOWERED_LATENCY_MS} ms: snakebot bus scan --latency-timer "
        f"{LOWERED_LATENCY_MS}, or echo {LOWERED_LATENCY_MS} | sudo tee {path} (writing it "
        f"needs root; a udev rule makes it stick: {UDEV_RULE})"
    )


def set_latency_timer(device: str, timer_ms: int, sysfs: Path = SYSFS_USB_SERIAL) -> None:
    """Set ``device``'s FTDI latency timer; :class:`PortError` says why it could not be."""
    path = latency_timer_path(device, sysfs)
    if not path.exists():
        raise PortError(
            device,
            f"{device} has no latency timer to set (not an FTDI adapter on Linux: {path} "
            "does not exist)",
        )
    try:
        path.write_text(f"{timer_ms}\n")
    except PermissionError:
        raise PortError(
            device,
            f"no permission to write {path}: it needs root (echo {timer_ms} | sudo tee "
            f"{path}), or a udev rule that sets it whenever the adapter is plugged in: "
            f"{UDEV_RULE}",
        ) from None
    except OSError as exc:
        raise PortError(device, f"could not set the latency timer in {path}: {exc}") from None
