"""Serial transport for Protocol 1.0: open a port by path or URL, and run transactions
on it with timeouts computed from the wire, echo and stale-reply handling, and retries.

    from snakebot.link.transport import DxlClient
    with DxlClient("/dev/ttyUSB0") as bus:        # or "sim://...", "socket://host:port"
        position = bus.read_u16(1, 36)

May import: ``formats``, ``facts`` and the package root; no other ``link`` package, and
never ``sim`` (``ports`` registers the ``sim://`` handler by its package name only).
"""

from __future__ import annotations

from snakebot.link.transport.client import DxlClient
from snakebot.link.transport.errors import PortError, TransportSettingError
from snakebot.link.transport.ports import open_port, register_handler_package
from snakebot.link.transport.settings import DEFAULT_RETRIES
from snakebot.link.transport.timing import (
    DEFAULT_BAUDRATE,
    DEFAULT_RETURN_DELAY_US,
    HOST_MARGIN_S,
    USB_LATENCY_S,
    BusTiming,
    reply_timeout_s,
    wire_time_s,
)

__all__ = [
    "DEFAULT_BAUDRATE",
    "DEFAULT_RETRIES",
    "DEFAULT_RETURN_DELAY_US",
    "HOST_MARGIN_S",
    "USB_LATENCY_S",
    "BusTiming",
    "DxlClient",
    "PortError",
    "TransportSettingError",
    "open_port",
    "register_handler_package",
    "reply_timeout_s",
    "wire_time_s",
]
