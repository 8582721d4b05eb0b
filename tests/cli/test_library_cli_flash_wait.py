"""`snakebot library` against a controller that writes its flash in the background, a
step per control tick, as the CM-530 does (the controller's C logic on a pty, its library
a Python store whose writes take ticks: tests/support/py_library.py): store and delete
wait for their write and report its outcome, play waits for the save of a table just
uploaded instead of being refused, and list says when a write is under way."""

from __future__ import annotations

import pytest
from controller_cli_support import cli, cli_json, save, wave_table
from py_library import FlashController, PyStore

from snakebot.core import lib
from snakebot.sim.controller_pty import ControllerPty

pytestmark = pytest.mark.timeout(120)


@pytest.fixture
def flash():
    """(the pty, the store) of a snake5 controller whose writes take 60 ticks (0.6 s)."""
    store = PyStore()
    store.write_in_background()
    store.ticks_per_write = 60
    server = ControllerPty(robot="snake5")
    server.device_logic = FlashController(server.bus, store)
    with server:
        yield server.device, store
        assert server.error is None, server.error


def test_store_waits_for_the_write_and_reports_the_stored_slot(flash, tmp_path):
    port, store = flash
    path = save(wave_table(), tmp_path)
    done = cli("library", "store", "2", str(path), "--name", "wave", "--port", port)
    assert done.exit_code == 0, done.output
    assert "writing the slot to its flash" in done.stderr
    assert "stored: 2  wave" in done.stdout and "OK" in done.stdout
    assert store.writing == lib.CTL_STORE_STATE_IDLE  # it returned once the write ended
    listed = cli_json("library", "list", "--port", port)
    assert listed["store"] == {"state": "IDLE", "percent": 0} and listed["memory"] == "FLASH"
    assert listed["slots"][2]["name"] == "wave" and listed["slots"][2]["status"] == "OK"
    deleted = cli_json("library", "delete", "2", "--port", port)
    assert deleted == {"slot": 2, "deleted": True} and 2 not in store.slots


def test_play_right_after_an_upload_waits_for_its_save_then_plays(flash, tmp_path):
    port, store = flash
    walk = save(wave_table(), tmp_path)
    assert cli("library", "store", "0", str(walk), "--port", port).exit_code == 0
    other = save(wave_table(frames=120), tmp_path, "other.gait")
    assert cli("upload", str(other), "--port", port).exit_code == 0
    # the controller saves the uploaded table for 0.6 s: a play now would replace it
    played = cli("library", "play", "0", "--port", port)
    assert played.exit_code == 0, played.output
    assert "waiting for the controller to finish saving its active table" in played.stderr
    assert "slot 0: PLAYING" in played.stdout
    assert cli("stop", "--port", port).exit_code == 0


def test_list_during_a_store_says_so(flash):
    port, store = flash
    store.ticks_per_write = 10**6  # a write that outlasts the test
    store.begin(lib.CTL_STORE_STATE_LIBRARY)
    listed = cli("library", "list", "--port", port)
    assert listed.exit_code == 0, listed.output
    assert "the controller is storing a library slot" in listed.stdout
    state = cli_json("library", "list", "--port", port)["store"]
    assert state["state"] == "LIBRARY" and 0 <= state["percent"] < 100


def test_a_backup_puts_every_slot_back_where_it_was(flash, tmp_path):
    """Two different tables in slots 0 and 2, backed up, both slots emptied, restored: each
    comes back in its own slot with its own bytes (the backup selects each slot before
    reading its window; after a list the window showed the last slot)."""
    port, store = flash
    store.ticks_per_write = 2
    tables = {0: save(wave_table(), tmp_path), 2: save(wave_table(frames=120), tmp_path, "b.gait")}
    for slot, path in tables.items():
        assert cli("library", "store", str(slot), str(path), "--port", port).exit_code == 0
    before = cli_json("library", "list", "--port", port)["slots"]
    saved = cli_json("library", "backup", str(tmp_path / "lib.json"), "--port", port)
    assert saved == {"file": str(tmp_path / "lib.json"), "slots": 2}
    for slot in tables:
        assert cli("library", "delete", str(slot), "--port", port).exit_code == 0
    assert not store.slots
    restored = cli_json("library", "restore", str(tmp_path / "lib.json"), "--port", port)
    assert sorted(s["slot"] for s in restored["restored"]) == [0, 2]
    after = cli_json("library", "list", "--port", port)["slots"]
    assert after == before and before[0]["crc"] != before[2]["crc"]
