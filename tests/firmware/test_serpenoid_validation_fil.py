"""The firmware image on both emulated boards (the CM-530's on the emulated STM32F103RE,
the qemu board's under QEMU) refuses the serpenoid of issue #13 (A 80 deg, omega 10 rad/s,
delta 60 deg, offset 30 deg on snake5) sent straight to it, with Refusal Reason AMPLITUDE
on the Program page, and a live change past the limits with RANGE; each reports its own
board's Table Capacity."""

from __future__ import annotations

import math

import pytest
from firmware_support import BOARDS, board_value, booted

from snakebot.link.controller.client import ControllerClient
from snakebot.link.controller.errors import ControllerError
from snakebot.link.controller.playback import roster_from_robot
from snakebot.model.robots import load_robot

pytestmark = pytest.mark.qemu


def mrad(rad: float) -> int:
    return round(rad * 1000)


@pytest.fixture(scope="module", params=BOARDS)
def running(request, tmp_path_factory):
    """(board, its PC link) with the board's firmware running."""
    with booted(request.param, tmp_path_factory.mktemp("bus")) as pc_link:
        yield request.param, pc_link


def test_the_issue_serpenoid_is_refused_on_board(running):
    board, port = running
    with ControllerClient.open(port) as ctl:
        reasons = ctl.table.enums["Refusal Reason"]
        ctl.set_roster(roster_from_robot(load_robot("snake5")))
        ctl.command("CLEAR")
        ctl.write(
            {
                "Serp Amplitude": mrad(math.radians(80)),
                "Serp Omega": mrad(10.0),
                "Serp Delta": mrad(math.radians(60)),
                "Serp Phi0": mrad(math.radians(30)),
            }
        )
        ctl.command("SERPENOID")
        after = ctl.read("State", "Error Flags", "Refusal Reason", "Table Capacity")
        assert after["State"] == ctl.table.enums["State"]["IDLE"]
        assert after["Error Flags"] & ctl.table.enums["Error Flags"]["REFUSED"]
        assert after["Refusal Reason"] == reasons["AMPLITUDE"]
        assert after["Table Capacity"] == board_value(board, "BOARD_TABLE_CAPACITY")
        # within the limits it runs, and a live change past them is refused with RANGE
        ctl.command("CLEAR")
        ctl.write({"Serp Amplitude": mrad(0.5), "Serp Omega": mrad(2.0), "Serp Phi0": 0})
        ctl.command("SERPENOID")
        assert ctl.read("State")["State"] == ctl.table.enums["State"]["SERPENOID"]
        with pytest.raises(ControllerError, match="refused WRITE"):
            ctl.write({"Serp Phi0": mrad(math.radians(70))})  # 70 + 28.6 > 90 deg
        assert ctl.read("Serp Phi0", "Refusal Reason") == {
            "Serp Phi0": 0,
            "Refusal Reason": reasons["AMPLITUDE"],
        }
        assert ctl.read("State")["State"] == ctl.table.enums["State"]["SERPENOID"]
        ctl.command("STOP")
