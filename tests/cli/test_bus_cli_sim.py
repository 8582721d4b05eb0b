"""`snakebot bus` against the emulated bus in process (sim://) and on a pseudo-terminal."""

from __future__ import annotations

import itertools
import json

import pytest
from click.testing import CliRunner

import snakebot.link.transport.ports  # noqa: F401  (registers sim://)
from snakebot.cli import main
from snakebot.formats.protocol import ControlTable
from snakebot.sim.options import SimOptions
from snakebot.sim.transports import PtyServer
from snakebot.sim.urlhandler.protocol_sim import forget_named_buses

pytestmark = pytest.mark.timeout(120)

AX12A = ControlTable.for_model("AX-12A")
EMULATED_FIRMWARE = AX12A.by_name("Firmware Version").emulator_default
_names = itertools.count()


@pytest.fixture(autouse=True)
def steady_timing(monkeypatch):
    # A reply timeout with room for a busy machine: a scan's silent IDs each cost one.
    monkeypatch.setenv("SNAKEBOT_LATENCY_MS", "30")
    yield
    forget_named_buses()


def new_bus(query: str) -> str:
    """A named emulated bus that keeps its servos between commands, as a powered robot."""
    return f"sim://bus{next(_names)}?{query}"


def bus(*args: str):
    return CliRunner().invoke(main, ["bus", *args])


def found_ids(result) -> list[int]:
    assert result.exit_code == 0, result.output
    return [s["id"] for s in json.loads(result.stdout)["found"]]


def test_scan_finds_each_servo_with_model_and_firmware():
    port = new_bus("ids=1,2,7")
    result = bus("scan", "--port", port, "--ids", "0-9", "--json")
    report = json.loads(result.stdout)
    assert [s["id"] for s in report["found"]] == [1, 2, 7]
    for servo in report["found"]:
        assert servo["model"] == "AX-12A" and servo["model_number"] == 12
        assert servo["firmware"] == EMULATED_FIRMWARE
        assert servo["baud"] == 1_000_000 and servo["error"] == 0
    text = bus("scan", "--port", port, "--ids", "0-9")
    assert text.exit_code == 0
    assert "Found 3 servos." in text.stdout
    assert "AX-12A (model 12)" in text.stdout


def test_scan_names_the_ax12w_and_covers_the_top_ids():
    result = bus("scan", "--port", new_bus("ids=253&model=AX-12W"), "--ids", "250-253", "--json")
    (servo,) = json.loads(result.stdout)["found"]
    assert (servo["id"], servo["model"], servo["model_number"]) == (253, "AX-12W", 300)


def test_scan_over_several_baud_rates_finds_a_servo_left_at_another_rate():
    port = new_bus("ids=4&baud=500000")
    alone = bus("scan", "--port", port, "--ids", "3-5", "--json")
    assert alone.exit_code == 1 and json.loads(alone.stdout)["found"] == []
    result = bus("scan", "--port", port, "--ids", "3-5", "--bauds", "1000000,500000", "--json")
    (servo,) = json.loads(result.stdout)["found"]
    assert (servo["id"], servo["baud"]) == (4, 500_000)


def test_scan_that_finds_nothing_says_what_to_check():
    result = bus("scan", "--port", new_bus("ids=40"), "--ids", "1-3")
    assert result.exit_code == 1
    assert "no servo answered" in result.stderr and "--bauds common" in result.stderr


def test_ping_reports_found_and_fails_for_missing():
    port = new_bus("ids=1,2")
    ok = bus("ping", "1", "2", "--port", port, "--json")
    assert [s["id"] for s in json.loads(ok.stdout)["found"]] == [1, 2]
    partly = bus("ping", "2", "3", "--port", port)
    assert partly.exit_code == 1  # no reply: the bus failed, the command line was fine
    assert "AX-12A" in partly.stdout
    assert "error[E203]: no reply from servo 3 at 1000000 baud" in partly.stderr


def test_read_decodes_registers_by_name_and_address():
    port = new_bus("ids=1&voltage=11.5")
    result = bus(
        "read", "1", "present-voltage", "0x24", "Return_Delay_Time", "--port", port, "--json"
    )
    assert result.exit_code == 0, result.output
    report = json.loads(result.stdout)
    assert report["model"] == "AX-12A"
    values = {r["name"]: r for r in report["registers"]}
    assert list(values) == ["Return Delay Time", "Present Position", "Present Voltage"]
    assert values["Present Voltage"]["value"] == 115
    assert values["Present Voltage"]["physical"] == pytest.approx(11.5)
    assert values["Return Delay Time"]["physical"] == 500  # 250 x 2 us
    assert values["Present Position"]["value"] == 512


def test_read_all_lists_every_register_of_the_table():
    result = bus("read", "1", "--port", new_bus("ids=1"))
    assert result.exit_code == 0, result.output
    for entry in AX12A:
        assert entry.name in result.stdout
    assert (
        "Present Position       512 (+0 deg from the centre, 150.1 deg on the 0-300 dial)"
        in result.stdout
    )


def test_write_moves_the_servo_and_reads_back():
    port = new_bus("ids=1&ideal=1")
    result = bus("write", "1", "goal-position", "600", "--port", port)
    assert result.exit_code == 0, result.output
    assert "Goal Position (30) = 600" in result.stdout and "reads back the same" in result.stdout
    after = bus("read", "1", "present-position", "--port", port, "--json")
    assert json.loads(after.stdout)["registers"][0]["value"] == 600
    led = bus("write", "1", "led", "1", "--port", port, "--json")
    assert json.loads(led.stdout) == {
        "id": 1,
        "register": "LED",
        "address": 25,
        "value": 1,
        "read_back": 1,
    }


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["present-position", "3"], "Present Position (address 36) is read-only"),
        (["goal-position", "1024"], "Goal Position takes 0-1023, not 1024"),
        (["punch", "31"], "Punch takes 32-1023, not 31"),
        (["id", "3"], "change ID with `snakebot bus set-id`"),
        (["baud-rate", "3"], "change Baud Rate with `snakebot bus set-baud`"),
        (["frob", "3"], "has no register 'frob'"),
        (["99", "3"], "no AX-12A register starts at address 99"),
        (["led", "on"], "cannot read the value 'on'"),
    ],
)
def test_bad_writes_are_refused_before_anything_is_sent(args, message):
    # The port does not exist: the refusal must come before it is opened.
    result = bus("write", "1", *args, "--port", "/dev/ttySNAKEBOT-missing")
    assert result.exit_code == 2
    assert message in result.stderr
    assert "does not exist" not in result.stderr


def test_set_id_refuses_a_taken_id_and_renumbers_to_a_free_one():
    port = new_bus("ids=1,2")
    taken = bus("set-id", "1", "2", "--port", port)
    assert taken.exit_code == 1
    assert "ID 2 is already taken" in taken.stderr
    assert found_ids(bus("scan", "--port", port, "--ids", "0-3", "--json")) == [1, 2]
    moved = bus("set-id", "1", "9", "--port", port, "--json")
    assert moved.exit_code == 0, moved.output
    assert json.loads(moved.stdout)["servo"]["id"] == 9
    assert found_ids(bus("scan", "--port", port, "--ids", "0-10", "--json")) == [2, 9]
    missing = bus("set-id", "5", "6", "--port", port)
    assert missing.exit_code == 1 and "no servo answers at ID 5" in missing.stderr


def test_set_baud_changes_the_rate_and_the_servo_answers_only_there():
    port = new_bus("ids=1")
    result = bus("set-baud", "1", "500000", "--port", port)
    assert result.exit_code == 0, result.output
    assert "2,000,000 / (3 + 1)" in result.stdout and "--baud 500000" in result.stdout
    assert bus("ping", "1", "--port", port).exit_code == 1
    assert bus("ping", "1", "--port", port, "--baud", "500000").exit_code == 0
    again = bus("set-baud", "1", "--value", "1", "--port", port, "--baud", "500000", "--json")
    assert json.loads(again.stdout) == {
        "id": 1,
        "register": 1,
        "servo_baud": 1_000_000.0,
        "host_baud": 1_000_000,
        "verified": True,
    }
    assert bus("ping", "1", "--port", port).exit_code == 0


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["300000"], "an AX-12 cannot run at 300000 bit/s"),
        ([], "error: --value: give either the rate (bit/s) or the Baud Rate register value"),
        (["500000", "--value", "3"], "error: --value: give either the rate"),
    ],
)
def test_set_baud_refuses_impossible_requests(args, message):
    result = bus("set-baud", "1", *args, "--port", "/dev/ttySNAKEBOT-missing")
    assert result.exit_code == 2
    assert message in result.stderr


def test_every_bus_command_has_help():
    for command in ("scan", "ping", "read", "write", "set-id", "set-baud"):
        result = bus(command, "--help")
        assert result.exit_code == 0
        assert "--port" in result.stdout and "--json" in result.stdout


def test_commands_work_on_the_pty_server(monkeypatch):
    monkeypatch.setenv("SNAKEBOT_LATENCY_MS", "50")  # real time on a pty: be generous
    emulated = SimOptions.from_query("ids=3,4").build_bus()
    with PtyServer(emulated) as server:
        assert found_ids(bus("scan", "--port", server.device, "--ids", "2-5", "--json")) == [3, 4]
        assert bus("set-baud", "4", "250000", "--port", server.device).exit_code == 0
        both = bus(
            "scan", "--port", server.device, "--ids", "3-4", "--bauds", "1000000,250000", "--json"
        )
        assert [(s["id"], s["baud"]) for s in json.loads(both.stdout)["found"]] == [
            (3, 1_000_000),
            (4, 250_000),
        ]
        read = bus("read", "3", "model-number", "--port", server.device, "--json")
        assert json.loads(read.stdout)["registers"][0]["value"] == 12
