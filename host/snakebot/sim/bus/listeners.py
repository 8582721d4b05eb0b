"""Who hears the wire: the powered servos grouped by baud rate, each group with the
receiver its members share (servos at one rate hear the same bytes, so they find the
same packets) and an index of them by ID; rebuilt when a servo changes baud rate or ID
or loses or regains power."""

from __future__ import annotations

import math

from snakebot.core import ffi
from snakebot.sim.bus.receiver import ServoReceiver
from snakebot.sim.bus.state import BusState
from snakebot.sim.servo.fast import VirtualServo


class Receiver:
    """The servos that share one baud rate, and the receive state they share (they hear
    the same bytes, so they find the same packets)."""

    __slots__ = ("baud", "parser", "last_t", "queued")

    def __init__(self, baud: float) -> None:
        self.baud = baud
        self.parser = ServoReceiver()
        self.last_t = -math.inf
        self.queued = 0  # deliveries scheduled and not yet made


class Group:
    """The powered servos at one baud rate: their shared receiver, the servos in bus
    order, and an index of them by ID (several when IDs collide), so a packet for one
    ID costs the same however many servos share the line.

    Packets already on their way keep the group they were sent to, as its servos were
    listening then; but a servo answers to the ID it has when a packet lands, so the
    index is rebuilt when IDs have changed since (``epoch``: the bus's count of link
    changes it was built at)."""

    __slots__ = ("rx", "members", "by_id", "c_by_id", "epoch", "c_path")

    def __init__(
        self, rx: Receiver, members: list[VirtualServo], epoch: int, c_path: bool = True
    ) -> None:
        self.rx = rx
        self.members = members
        self.c_path = c_path
        self.reindex(epoch)

    def reindex(self, epoch: int) -> None:
        self.by_id: dict[int, list[VirtualServo]] = {}
        for s in self.members:
            self.by_id.setdefault(s.id, []).append(s)
        self.epoch = epoch
        # The same index for the C servos (a SYNC_WRITE handled in one call), when every
        # servo here is one and no two share an ID; None otherwise.
        self.c_by_id = None
        structs = [getattr(s, "c_struct", None) for s in self.members]
        if self.c_path and None not in structs and len(self.by_id) == len(self.members):
            self.c_by_id = ffi.new("sim_servo *[256]")
            for s, struct in zip(self.members, structs, strict=True):
                self.c_by_id[s.id] = struct


class Listeners(BusState):
    """The bus's servos as the wire's listeners (a part of
    :class:`~snakebot.sim.bus.bus.Bus`)."""

    def tap(self) -> None:
        """From now on every packet goes through the servos' Python handlers
        (``receive``, ``sync_write_block``), slower than handing whole packets to the C
        servos, so that a test or a tool that wraps those handlers hears every one."""
        self._c_path = False
        self._groups = None

    def _link_changed(self, _servo: VirtualServo) -> None:
        # a servo changed baud rate or ID, or lost/regained power
        self._groups = None
        self._by_id = None
        self._link_epoch += 1

    def _listeners(self) -> list[Group]:
        """The powered servos grouped by baud rate, each group with its shared parser."""
        if self._groups is None:
            by_baud: dict[float, list[VirtualServo]] = {}
            for s in self.servos:
                if s.powered:
                    by_baud.setdefault(s.baudrate, []).append(s)
            groups = []
            for baud, members in by_baud.items():
                rx = self._receivers.get(baud)
                if rx is None:
                    rx = self._receivers[baud] = Receiver(baud)
                groups.append(Group(rx, members, self._link_epoch, self._c_path))
            self._groups = groups
            # see _deliver_read
            plain = len(groups) == 1 and not (self._corrupting or self._reply_faults)
            self._quiet_reply = groups[0] if plain else None
        return self._groups
