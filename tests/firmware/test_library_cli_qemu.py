"""`snakebot library` against the real firmware image under QEMU (what `snakebot sim
serve` runs): QEMU's one-slot library, which aliases the active table, stored, listed,
played, pressed with the emulated buttons and deleted through the PC link."""

from __future__ import annotations

import time
import zlib

import pytest
from controller_cli_support import cli, cli_json, save, wave_table
from firmware_support import served_firmware

from snakebot.link.controller import load
from snakebot.link.controller.client import ControllerClient
from snakebot.link.controller.library import backup, delete_slot, read_slot, restore
from snakebot.link.flash.library_backup import backup_library, restore_library

# QEMU behind a pty: its replies come late when another worker loads the machine
pytestmark = [pytest.mark.qemu, pytest.mark.serial]

CTL = load()


@pytest.fixture(scope="module")
def firmware(tmp_path_factory):
    with served_firmware(tmp_path_factory.mktemp("bus")) as port:
        yield port


def test_store_list_play_stop_delete(firmware, tmp_path):
    path = save(wave_table(), tmp_path)
    blob = path.read_bytes()
    listed = cli_json("library", "list", "--port", firmware)
    assert listed["slots"] == [
        {"slot": 0, "status": "EMPTY", "kind": "NONE", "length": 0, "crc": 0, "name": ""}
    ]
    # QEMU keeps its library in RAM and writes no flash in the background
    assert listed["memory"] == "RAM" and listed["store"] == {"state": "IDLE", "percent": 0}
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
    assert "keeps its library in RAM" in listed.stdout and "power-off" in listed.stdout

    played = cli_json("library", "play", "0", "--port", firmware)
    assert played == {"slot": 0, "state": "PLAYING"}
    assert cli("stop", "--port", firmware).exit_code == 0

    # QEMU's library has one slot: slot 1 is refused (bad input), by name, with the fix
    for refused in (
        cli("library", "play", "1", "--port", firmware),
        cli("library", "store", "1", path, "--port", firmware),
    ):
        assert refused.exit_code == 2
        assert refused.stderr.startswith("error: slot 1 does not exist: this controller keeps")
        assert "in RAM" in refused.stderr and "use slot 0" in refused.stderr
    bad_name = cli("library", "store", "0", path, "--name", "é", "--port", firmware)
    assert bad_name.exit_code == 2 and "printable ASCII" in bad_name.stderr

    assert cli_json("library", "delete", "0", "--port", firmware)["deleted"]
    empty = cli("library", "play", "0", "--port", firmware)
    assert empty.exit_code == 2 and "LIBRARY_EMPTY" in empty.stderr


def test_the_buttons_play_and_stop_and_a_backup_restores(firmware, tmp_path):
    path = save(wave_table(frames=50), tmp_path)
    assert cli("library", "store", "0", path, "--port", firmware).exit_code == 0
    with ControllerClient.open(firmware, controller_id=CTL.default_id) as ctl:
        start = CTL.enums["Buttons"]["START"]
        for held in (start, 0):  # hold START long enough to count, then let go
            ctl.write({"Buttons": held})
            time.sleep(0.2)
        r = ctl.read("State", "LEDs", "Panel Slot")
        assert r["State"] == CTL.enums["State"]["PLAYING"]
        assert r["LEDs"] == CTL.enums["LEDs"]["PLAY"] and r["Panel Slot"] == 0
        for held in (start, 0):
            ctl.write({"Buttons": held})
            time.sleep(0.2)
        assert ctl.read("State")["State"] == CTL.enums["State"]["IDLE"]

        saved = backup(ctl)
        assert saved["slots"][0]["name"] == "walk" and "data" in saved["slots"][0]
        assert restore(ctl, saved) == []  # already in place: nothing written
        delete_slot(ctl, 0)
        assert read_slot(ctl, 0).status == "EMPTY"
        written = restore(ctl, saved)
        assert [(s.slot, s.status, s.crc) for s in written] == [
            (0, "OK", zlib.crc32(path.read_bytes()))
        ]


def test_flash_backup_saves_the_library_and_restores_what_flashing_lost(
    firmware, tmp_path, monkeypatch
):
    """The two halves `snakebot flash` wraps around the bootloader, against the firmware:
    QEMU cannot run the ROBOTIS bootloader, so the erase it might do is a LIBRARY_DELETE."""
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
