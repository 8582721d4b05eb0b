"""What a :class:`~snakebot.link.transport.client.DxlClient` keeps, declared once for the
parts that share it.

The client is one object made of several parts, each a class in its own module
(``levels``, ``transaction``, ``reply``, ``reads``, ``writes``) that works on the same
attributes: a transaction reads them straight off the one instance, with no call
between the parts beyond their own methods. :class:`ClientState` names those
attributes and their types; ``DxlClient.__init__`` sets them.
"""

from __future__ import annotations

import threading
from collections import deque
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    import serial

    from snakebot.facts.devices import Device
    from snakebot.formats.protocol import PacketParser
    from snakebot.link.transport.portio import PortIO
    from snakebot.link.transport.reads import RangeCheck, ReadPlan
    from snakebot.link.transport.timing import BusTiming


class ClientState:
    """The attributes every part of the client works on (annotations only: no values)."""

    # the port
    _port: serial.SerialBase
    _owns_port: bool
    _io: PortIO
    _read_timeout: float | None
    _lock: threading.RLock  # one transaction on the wire at a time
    # transactions and their timing
    retries: int
    _timing: BusTiming
    _timeouts: dict[tuple[int, int], float]  # reply timeouts by (packet, reply) length
    # replies and echo
    echo_probe_s: float
    _echo: bool | None  # None: not known yet ("auto" before the first answered transaction)
    _parser: PacketParser
    _recent: deque[bytes]  # the last instructions sent, to know their late echoes
    # Status Return Level
    _default_level: int
    _levels: dict[int, int]
    _level_address: int | None
    # READs and the device's ranges
    device: Device
    check_ranges: bool
    _range_checks: dict[tuple[int, int], list[RangeCheck]]
    _read_plans: dict[tuple[int, int, int], ReadPlan]
