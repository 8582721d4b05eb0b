"""The controller client reads and writes registers of window pages by name: it writes
Window Page first, over a real pty to the controller's C core (ControllerPty)."""

from __future__ import annotations

from snakebot.link.controller import load
from snakebot.link.controller.client import ControllerClient, RosterEntry
from snakebot.sim.controller_pty import ControllerPty

CTL = load()


def test_page_registers_are_read_by_name_beside_ordinary_ones():
    with ControllerPty(robot="snake5") as server, ControllerClient.open(server.device) as ctl:
        ctl.set_roster([RosterEntry(id=10), RosterEntry(id=11, reverse=True)])
        values = ctl.read("Speed Scale", "Table Capacity", "Max Segments", "Joint Count")
        assert values["Table Capacity"] == CTL.limits["max_table_bytes"]
        assert values["Max Segments"] == CTL.limits["max_program_segments"]
        assert values["Speed Scale"] == CTL.register("Speed Scale").default
        assert ctl.read("Window Page")["Window Page"] == CTL.page("Program").number
        # the roster still reads through pages 0..2 afterwards
        assert [(j.id, j.reverse) for j in ctl.roster()] == [(10, 0), (11, 1)]


def test_a_refusal_reason_is_read_after_the_refused_command():
    with ControllerPty(robot="snake5") as server, ControllerClient.open(server.device) as ctl:
        ctl.write({"Joint Count": 0})
        ctl.command("SERPENOID")
        reasons = CTL.enums["Refusal Reason"]
        assert ctl.read("Refusal Reason") == {"Refusal Reason": reasons["EMPTY_ROSTER"]}
