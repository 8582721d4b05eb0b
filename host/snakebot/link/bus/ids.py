"""Changing a servo's ID or baud rate: refused when the new ID is taken or the rate cannot
be reached, then confirmed by finding the servo where it should now be."""

from __future__ import annotations

from dataclasses import dataclass

from snakebot.formats import protocol
from snakebot.formats.protocol import (
    BROADCAST_ID,
    MAX_ID,
)
from snakebot.formats.register_values import (
    BusCommandError,
    base_table,
    baud_from_register,
    check_write,
)
from snakebot.link.bus.registers import send_and_settle, servo_table
from snakebot.link.bus.scan import ServoInfo, identify
from snakebot.link.transport import DxlClient


def set_id(client: DxlClient, old: int, new: int) -> ServoInfo:
    """Give the servo at ``old`` the ID ``new``; refuses an ID another device answers to.
    Returns the servo as found at its new ID."""
    for what, servo_id in (("current", old), ("new", new)):
        if not 0 <= servo_id <= MAX_ID:
            raise BusCommandError(
                f"the {what} ID {servo_id} is not a servo ID: use 0-{MAX_ID} "
                f"({BROADCAST_ID} is broadcast)"
            )
    if old == new:
        raise BusCommandError(f"servo {old} already has ID {new}: nothing to do")
    check_write(base_table().by_name("ID"), new)
    if identify(client, old) is None:
        raise BusCommandError(
            f"no servo answers at ID {old} at {client.baudrate} baud: check the ID and baud "
            "rate with snakebot bus scan"
        )
    taken = identify(client, new)
    if taken is not None:
        raise BusCommandError(
            f"ID {new} is already taken on this bus ({taken.label} answers there): two "
            "servos with one ID garble each other's replies. Pick a free ID (snakebot bus "
            "scan lists the IDs in use)"
        )
    address = servo_table(client, old).by_name("ID").address
    send_and_settle(client, protocol.write(old, address, bytes([new])))
    moved = identify(client, new)
    if moved is None:
        still = identify(client, old) is not None
        raise BusCommandError(
            f"servo {old} did not take ID {new}"
            + (
                ": it still answers at its old ID, so it refused the write (is its EEPROM "
                "locked? Lock is cleared by a power cycle)"
                if still
                else " and no longer answers at either ID: scan the bus (snakebot bus scan)"
            )
        )
    return moved


@dataclass(frozen=True)
class BaudChange:
    """The outcome of :func:`set_baud`."""

    id: int
    register: int
    servo_baud: float  # what the servo now runs at
    host_baud: int  # the rate the host reopened at to check
    verified: bool


def set_baud(client: DxlClient, servo_id: int, register: int, host_baud: int) -> BaudChange:
    """Write Baud Rate ``register`` to ``servo_id``, then reopen the port at ``host_baud``
    and PING the servo there. Raises :class:`BusCommandError` if it does not answer."""
    entry = base_table().by_name("Baud Rate")
    check_write(entry, register)
    if identify(client, servo_id) is None:
        raise BusCommandError(
            f"no servo answers at ID {servo_id} at {client.baudrate} baud: find it first "
            "(snakebot bus scan --bauds common)"
        )
    old_baud = client.baudrate
    address = servo_table(client, servo_id).by_name("Baud Rate").address
    send_and_settle(client, protocol.write(servo_id, address, bytes([register])))
    if identify(DxlClient(client.port, host_baud), servo_id) is not None:
        return BaudChange(servo_id, register, baud_from_register(register), host_baud, True)
    still = identify(DxlClient(client.port, old_baud), servo_id) is not None
    raise BusCommandError(
        f"servo {servo_id} does not answer at {host_baud} baud after the change"
        + (
            f": it still answers at {old_baud}, so it refused the write (is its EEPROM "
            "locked? Lock is cleared by a power cycle)"
            if still
            else f" nor at {old_baud}: find it with snakebot bus scan --ids {servo_id} "
            "--bauds common"
        )
    )
