"""What the emulated bus keeps, declared once for the parts that share it.

:class:`~snakebot.sim.bus.bus.Bus` is one object made of several parts, each a class in
its own module (``schedule``, ``listeners``, ``wire``, ``delivery``, ``master``) that
works on the same attributes: the hot paths read them straight off the one instance,
with no call between the parts beyond their own methods. :class:`BusState` names those
attributes and their types; ``Bus.__init__`` sets them.
"""

from __future__ import annotations

import itertools
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from snakebot.sim.bus.faults import FaultConfig, FaultInjector
    from snakebot.sim.bus.listeners import Group, Receiver
    from snakebot.sim.bus.wire import BusStats, Heard, Transmission
    from snakebot.sim.servo.fast import VirtualServo


class BusState:
    """The attributes every part of the bus works on (annotations only: no values)."""

    # the clock and its events (schedule)
    now: float
    _events: list[tuple[float, int, Callable, object]]
    _seq: itertools.count[int]
    # the servos and who hears what (listeners)
    servos: list[VirtualServo]
    _receivers: dict[float, Receiver]
    _groups: list[Group] | None
    _quiet_reply: Group | None  # the group of _listeners, when alone
    _c_path: bool  # whole packets to the C servos (tap() turns it off)
    _link_epoch: int  # link changes so far (Group.epoch)
    _by_id: dict[int, VirtualServo] | None  # the first servo with each ID
    _indexed: int  # how many servos the index was built from
    # the wire (wire)
    baudrate: float
    echo: bool
    fault_config: FaultConfig
    faults: FaultInjector
    _corrupting: bool
    _reply_faults: bool
    stats: BusStats
    _wire: list[Transmission]
    _wire_end: float  # when the last of them ends
    _servo_tx_free: dict[int, float]
    # the C servos' answers (delivery)
    _c_reply: Any  # uint8_t[256]: a C servo's status packet
    _c_reply_bytes: Any  # its ffi buffer, sliced: a copy as bytes
    # one bound method, so that master_receive knows a READ's delivery by identity
    _deliver_read_cb: Callable[[float, tuple[Group, Transmission]], None]
    # the master's port (master)
    # a READ written and not yet on the wire or due (see master_write, _release):
    # (start, end, event sequence number, group, frame)
    _held: tuple[float, float, int, Group, bytes] | None
    _master_rx: list[Heard]
    _master_tx_free: float
