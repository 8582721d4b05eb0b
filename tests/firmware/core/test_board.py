"""The Board field (Program page): the board the app names at start-up, read-only; the
core itself knows no board and reports NONE until told."""

from __future__ import annotations

import pytest
from ctl_support import CTL, CTL_ID, Device, lib_value

from snakebot.core import lib
from snakebot.formats.protocol import ErrorFlags, reset, write

BOARD = CTL.register("Board")


def shown_board(dev: Device) -> int:
    assert dev.set("Window Page", CTL.page_number("Board")) == 0
    return dev.get("Board")


def test_the_core_alone_names_no_board():
    assert shown_board(Device()) == lib_value("Board", "NONE") == lib.CTL_BOARD_NONE


@pytest.mark.parametrize("name", ["CM530", "QEMU"])
def test_the_board_the_app_names_is_reported(name):
    dev = Device()
    value = lib_value("Board", name)
    assert value == getattr(lib, f"CTL_BOARD_{name}")  # the C constant is the JSON's value
    lib.ctl_set_board(dev.d, value)
    assert shown_board(dev) == value


def test_the_board_cannot_be_written():
    dev = Device()
    lib.ctl_set_board(dev.d, lib.CTL_BOARD_QEMU)
    assert dev.set("Window Page", CTL.page_number("Board")) == 0
    reply = dev.one(write(CTL_ID, BOARD.address, bytes([lib.CTL_BOARD_CM530])))
    assert reply.error == ErrorFlags.RANGE
    assert dev.get("Board") == lib.CTL_BOARD_QEMU


def test_a_factory_reset_of_the_registers_keeps_the_board():
    dev = Device()
    lib.ctl_set_board(dev.d, lib.CTL_BOARD_CM530)
    assert dev.one(reset(CTL_ID)).error == 0
    assert shown_board(dev) == lib.CTL_BOARD_CM530
