"""Reading and writing a servo's registers by name, in the servo's own control table (from
its Model Number); values are checked before anything is sent."""

from __future__ import annotations

import time
from collections.abc import Sequence

from snakebot.formats.protocol import (
    ControlTable,
    ControlTableError,
    Entry,
)
from snakebot.formats.register_values import BusCommandError, base_table, check_write, decode
from snakebot.link.transport import DxlClient

SETTLE_S = 0.01


"""Pause after an ID or baud change before the servo is addressed anew (it stores the
new value in EEPROM)."""


def servo_table(client: DxlClient, servo_id: int) -> ControlTable:
    """The control table of the servo at ``servo_id``, from its Model Number."""
    address = base_table().by_name("Model Number").address
    # Confirmed: the model decides which table every later register name is read from.
    number = int.from_bytes(client.read_confirmed(servo_id, address, 2), "little")
    try:
        return ControlTable.for_model_number(number)
    except ControlTableError:
        known = ", ".join(
            f"{ControlTable.for_model(m).model_number} ({m})" for m in ControlTable.models()
        )
        raise BusCommandError(
            f"servo {servo_id} reports model number {number}, which snakebot has no control "
            f"table for (known: {known}): its registers may sit elsewhere, so nothing was "
            "read or written by name"
        ) from None


def read_registers(
    client: DxlClient, servo_id: int, entries: Sequence[Entry]
) -> tuple[ControlTable, list[dict[str, object]]]:
    """Read ``entries`` (all registers if empty) in one READ; decoded, in address order."""
    table = servo_table(client, servo_id)
    chosen = sorted({table.by_name(e.name) for e in entries} or set(table), key=lambda e: e.address)
    start = chosen[0].address
    end = max(e.address + e.size for e in chosen)
    data = client.read(servo_id, start, end - start)
    values = []
    for entry in chosen:
        offset = entry.address - start
        raw = int.from_bytes(data[offset : offset + entry.size], "little")
        values.append(decode(entry, raw, table))
    return table, values


def write_register(client: DxlClient, servo_id: int, entry: Entry, value: int) -> int | None:
    """Write ``value`` to ``entry`` after checking it; returns the value read back (None if
    the servo's Status Return Level does not answer READs)."""
    check_write(entry, value)
    table = servo_table(client, servo_id)
    entry = table.by_name(entry.name)
    client.write(servo_id, entry.address, value.to_bytes(entry.size, "little"))
    if client.status_return_level(servo_id) < 1:
        return None
    read_back = client.read_confirmed(servo_id, entry.address, entry.size)  # it verifies
    return int.from_bytes(read_back, "little")


def send_and_settle(client: DxlClient, packet: bytes) -> None:
    """Send an EEPROM change without waiting for its status (which may come from the new
    ID or at the old rate), let the reply pass, and discard it."""
    client.send(packet)
    time.sleep(client.timing.reply_timeout_s(len(packet), 0) + SETTLE_S)
    client.port.reset_input_buffer()
