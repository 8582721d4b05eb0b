"""`snakebot library` against the real firmware image on either board (what `snakebot sim
serve` runs): stored, listed, played, pressed with the buttons and deleted through the
PC link. The CM-530 keeps STORE_LIB_SLOTS slots in flash beside its active table; QEMU's
one-slot library lives in RAM and aliases the active table."""

from __future__ import annotations

import time
import zlib

import pytest
from controller_cli_support import cli, cli_json, save, wave_table
from firmware_support import BOARDS, Running, running

from snakebot.core import lib
from snakebot.link.controller import load
from snakebot.link.controller.client import ControllerClient
from snakebot.link.controller.library import (
    backup,
    delete_slot,
    read_slot,
    restore,
    store_slot,
)
from snakebot.link.flash.library_backup import backup_library, restore_library

# QEMU behind a pty, the emulated CM-530 in the tests' own process: their replies come
# late when another worker loads the machine
pytestmark = [pytest.mark.qemu, pytest.mark.serial]

CTL = load()
SLOTS = {"cm530": lib.CTL_MAX_LIBRARY_SLOTS, "qemu": 1}  # app/store_lib.h, app/store_play.c
MEMORY = {"cm530": "FLASH", "qemu": "RAM"}
EMPTY = {"status": "EMPTY", "kind": "NONE", "length": 0, "crc": 0, "name": ""}

# The CM-530's buttons and LEDs (firmware/boards/cm530/board.h): active low, as
# (port, pin); AUX shows the LEDs register's SLOT_1. QEMU models no GPIO: its buttons are
# the Buttons register alone.
BUTTON_U, BUTTON_START = ("C", 11), ("B", 3)
LED_AUX, LED_PLAY = ("B", 12), ("B", 15)
PRESS_S = 0.2  # on the bus's clock: many times BUTTONS_DEBOUNCE_SCANS control ticks


@pytest.fixture(scope="module", params=BOARDS)
def robot(request, tmp_path_factory):
    with running(request.param, tmp_path_factory.mktemp("bus")) as fw:
        yield fw


def table_crc(port: str) -> int:
    with ControllerClient.open(port, controller_id=CTL.default_id) as ctl:
        return ctl.read("Table CRC")["Table CRC"]


def test_store_list_play_stop_delete(robot, tmp_path):
    firmware, board = robot.pc_link, robot.board
    path = save(wave_table(), tmp_path)
    blob = path.read_bytes()
    listed = cli_json("library", "list", "--port", firmware)
    assert listed["slots"] == [{"slot": s, **EMPTY} for s in range(SLOTS[board])]
    # the CM-530 writes its flash in the background (nothing to write yet); QEMU keeps its
    # library in RAM and writes no flash at all
    assert listed["memory"] == MEMORY[board] and listed["store"] == {"state": "IDLE", "percent": 0}
    active_before = table_crc(firmware)
    stored = cli_json("library", "store", "0", path, "--name", "wave", "--port", firmware)
    assert stored == {
        "slot": 0,
        "status": "OK",
        "kind": "TABLE",
        "length": len(blob),
        "crc": zlib.crc32(blob),
        "name": "wave",
    }
    listed = cli("library", "list", "--port", firmware)
    assert listed.exit_code == 0 and "wave" in listed.stdout and "OK" in listed.stdout
    in_ram = "keeps its library in RAM" in listed.stdout and "power-off" in listed.stdout
    assert in_ram == (board == "qemu")
    if board == "qemu":
        # the one slot is the active table: storing made it active
        assert table_crc(firmware) == zlib.crc32(blob) != active_before
    else:
        # a slot of its own: the active table is left alone
        assert table_crc(firmware) == active_before

    played = cli_json("library", "play", "0", "--port", firmware)
    assert played == {"slot": 0, "state": "PLAYING"}
    assert cli("stop", "--port", firmware).exit_code == 0

    if board == "qemu":
        # QEMU's library has one slot: slot 1 is refused (bad input), by name, with the fix
        for refused in (
            cli("library", "play", "1", "--port", firmware),
            cli("library", "store", "1", path, "--port", firmware),
        ):
            assert refused.exit_code == 2
            assert refused.stderr.startswith("error: slot 1 does not exist: this controller keeps")
            assert "in RAM" in refused.stderr and "use slot 0" in refused.stderr
    else:
        # the CM-530 keeps a second table in slot 1 beside the first, and plays either
        other = save(wave_table(frames=40), tmp_path, "other.gait")
        second = cli_json("library", "store", "1", other, "--port", firmware)
        assert (second["status"], second["name"]) == ("OK", "other")
        assert second["crc"] == zlib.crc32(other.read_bytes()) != zlib.crc32(blob)
        slots = cli_json("library", "list", "--port", firmware)["slots"]
        assert [(s["name"], s["crc"]) for s in slots[:2]] == [
            ("wave", zlib.crc32(blob)),
            ("other", zlib.crc32(other.read_bytes())),
        ]
        assert all(s["status"] == "EMPTY" for s in slots[2:])
        assert cli_json("library", "play", "1", "--port", firmware)["state"] == "PLAYING"
        assert table_crc(firmware) == zlib.crc32(other.read_bytes())
        assert cli("stop", "--port", firmware).exit_code == 0
        assert cli_json("library", "delete", "1", "--port", firmware)["deleted"]
        # past the last slot is refused (bad input), by name, with the slots there are
        last = SLOTS[board]
        for refused in (
            cli("library", "play", str(last), "--port", firmware),
            cli("library", "store", str(last), path, "--port", firmware),
        ):
            assert refused.exit_code == 2
            assert refused.stderr.startswith(
                f"error: slot {last} does not exist: this controller has slots 0..{last - 1}"
            )
    bad_name = cli("library", "store", "0", path, "--name", "é", "--port", firmware)
    assert bad_name.exit_code == 2 and "printable ASCII" in bad_name.stderr

    # another table made active: QEMU's slot was that table and is gone with it; the
    # CM-530's slot is kept
    other = save(wave_table(frames=60), tmp_path, "active.gait")
    assert cli("upload", other, "--port", firmware).exit_code == 0
    kept = cli_json("library", "list", "--port", firmware)["slots"][0]
    if board == "qemu":
        assert kept == {"slot": 0, **EMPTY}
        assert cli("library", "store", "0", path, "--port", firmware).exit_code == 0
    else:
        assert (kept["status"], kept["name"], kept["crc"]) == ("OK", "wave", zlib.crc32(blob))

    assert cli_json("library", "delete", "0", "--port", firmware)["deleted"]
    empty = cli("library", "play", "0", "--port", firmware)
    assert empty.exit_code == 2 and "LIBRARY_EMPTY" in empty.stderr


def hold_for(fw: Running, seconds: float) -> None:
    """Wait until ``seconds`` have passed on the servo bus's clock: the emulated CM-530's
    own time (a chip slowed by a busy host takes longer, but sees the press as long), the
    wall clock the bus is paced by under QEMU."""
    end, give_up = fw.bus_now() + seconds, time.monotonic() + 50 * seconds
    while fw.bus_now() < end:
        assert time.monotonic() < give_up, "the firmware's clock stood still"
        time.sleep(0.02)


def press(fw: Running, ctl: ControllerClient, button: int) -> None:
    """Hold ``button`` through the Buttons register long enough to count, then let go."""
    for held in (button, 0):
        ctl.write({"Buttons": held})
        hold_for(fw, PRESS_S)


def press_pin(fw: Running, pin: tuple[str, int]) -> None:
    """Hold the CM-530's button on ``pin`` down (it pulls its pin low) long enough to
    count, then let go."""
    port, number = pin
    for level in (False, None):
        with fw.lock:
            fw.firmware.board.mcu.gpio[port].drive(number, level)
        hold_for(fw, PRESS_S)


def lit(fw: Running, led: tuple[str, int]) -> bool:
    """The CM-530's LED on ``led`` is lit: its pin an output driven low."""
    port, number = led
    with fw.lock:
        return fw.firmware.board.mcu.gpio[port].output(number) is False


def test_the_buttons_play_and_stop_and_a_backup_restores(robot, tmp_path):
    firmware, board = robot.pc_link, robot.board
    path = save(wave_table(frames=50), tmp_path)
    assert cli("library", "store", "0", path, "--port", firmware).exit_code == 0
    with ControllerClient.open(firmware, controller_id=CTL.default_id) as ctl:
        start = CTL.enums["Buttons"]["START"]
        press(robot, ctl, start)
        r = ctl.read("State", "LEDs", "Panel Slot")
        assert r["State"] == CTL.enums["State"]["PLAYING"]
        assert r["LEDs"] == CTL.enums["LEDs"]["PLAY"] and r["Panel Slot"] == 0
        press(robot, ctl, start)
        assert ctl.read("State")["State"] == CTL.enums["State"]["IDLE"]

        if board == "cm530":
            # the board's own buttons and LEDs: U picks slot 1 (AUX shows it), START
            # plays it (PLAY lights) and stops it
            other = save(wave_table(frames=40), tmp_path, "other.gait")
            assert store_slot(ctl, 1, "other", other.read_bytes()).status == "OK"
            assert not lit(robot, LED_AUX) and not lit(robot, LED_PLAY)
            press_pin(robot, BUTTON_U)
            assert ctl.read("Panel Slot")["Panel Slot"] == 1
            assert lit(robot, LED_AUX) and not lit(robot, LED_PLAY)
            press_pin(robot, BUTTON_START)
            r = ctl.read("State", "Table CRC", "LEDs")
            assert r["State"] == CTL.enums["State"]["PLAYING"]
            assert r["Table CRC"] == zlib.crc32(other.read_bytes())
            assert r["LEDs"] == CTL.enums["LEDs"]["PLAY"] | CTL.enums["LEDs"]["SLOT_1"]
            assert lit(robot, LED_AUX) and lit(robot, LED_PLAY)
            press_pin(robot, BUTTON_START)
            assert ctl.read("State")["State"] == CTL.enums["State"]["IDLE"]
            assert not lit(robot, LED_PLAY)
            delete_slot(ctl, 1)
        else:
            # one slot: U wraps round to slot 0
            press(robot, ctl, CTL.enums["Buttons"]["U"])
            assert ctl.read("Panel Slot")["Panel Slot"] == 0

        saved = backup(ctl)
        assert len(saved["slots"]) == SLOTS[board]
        assert saved["slots"][0]["name"] == "walk" and "data" in saved["slots"][0]
        assert all("data" not in s for s in saved["slots"][1:])
        assert restore(ctl, saved) == []  # already in place: nothing written
        delete_slot(ctl, 0)
        assert read_slot(ctl, 0).status == "EMPTY"
        written = restore(ctl, saved)
        assert [(s.slot, s.status, s.crc) for s in written] == [
            (0, "OK", zlib.crc32(path.read_bytes()))
        ]


def test_flash_backup_saves_the_library_and_restores_what_flashing_lost(
    robot, tmp_path, monkeypatch
):
    """The two halves `snakebot flash` wraps around the bootloader, against the firmware:
    the erase flashing might do is a LIBRARY_DELETE here (QEMU cannot run the ROBOTIS
    bootloader at all)."""
    firmware = robot.pc_link
    monkeypatch.setenv("SNAKEBOT_LIBRARY_BACKUP_DIR", str(tmp_path / "backups"))
    path = save(wave_table(frames=30), tmp_path, "crawl.gait")
    assert cli("library", "store", "0", path, "--port", firmware).exit_code == 0
    said: list[str] = []
    warned: list[str] = []
    saved = backup_library(firmware, said.append, warned.append)
    assert saved is not None and saved.parent == tmp_path / "backups" and warned == []
    assert said == [f"Backed up 1 gait-library slot(s) to {saved}"]
    restore_library(firmware, saved, said.append, warned.append)
    assert said[-1] == "The gait library survived flashing: nothing to restore."
    assert cli("library", "delete", "0", "--port", firmware).exit_code == 0
    restore_library(firmware, saved, said.append, warned.append)
    assert said[-1] == f"Restored 1 gait-library slot(s) from {saved}" and warned == []
    listed = cli_json("library", "list", "--port", firmware)["slots"]
    assert listed[0]["name"] == "crawl" and listed[0]["crc"] == zlib.crc32(path.read_bytes())
    # and the command that restores by hand
    assert cli("library", "delete", "0", "--port", firmware).exit_code == 0
    by_hand = cli_json("library", "restore", saved, "--port", firmware)
    assert [s["name"] for s in by_hand["restored"]] == ["crawl"]
