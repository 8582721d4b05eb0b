"""The fault campaigns' own view of the machine (``Rig.check_view`` in
tests/reliability/rig/campaigns/), on both boards: what the rig reads from the firmware's
RAM (through QEMU's monitor, or from the emulated CM-530 under its lock) counts only once
it is shown to be the running firmware's, so a wrong RAM map, an ELF from another build,
another QEMU's monitor or an emulated chip that stopped is reported as the rig failing
(``CampaignFailed``, exit 2), never as the firmware breaking a promise; a real reboot is
reported with the CPU's PC and SP and the machine's log; and on the CM-530, whose
emulation models the watchdog, a watchdog reset fails the alive check."""

from __future__ import annotations

import dataclasses
import tempfile
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
from firmware_support import APP_BASE, BOARDS, STUB_BASE, build_firmware

from snakebot.link.controller import UploadResult
from snakebot.sim.bus.faults import FaultConfig
from tests.reliability.rig import campaigns
from tests.reliability.rig.campaigns import (
    TARGETS,
    CampaignFailed,
    Outcome,
    RamMap,
    Rig,
    gait_table,
)
from tests.reliability.rig.campaigns.bus_faults import watchdog_checks

pytestmark = [pytest.mark.qemu, pytest.mark.slow, pytest.mark.serial]

IMAGE_BASE = {"cm530": APP_BASE, "qemu": STUB_BASE}
"""Where each board's image starts in flash: the CM-530's at the application's base (the
bootloader lies below), QEMU's is the whole flash, its boot stub first."""


@pytest.fixture(scope="module", params=BOARDS)
def board(request: pytest.FixtureRequest) -> str:
    if request.param == "cm530":
        pytest.importorskip("unicorn")
    return request.param


@pytest.fixture(scope="module")
def ram(board: str) -> RamMap:
    build_firmware()
    return RamMap.from_build(TARGETS[board].elf)


@pytest.fixture
def workdir() -> Iterator[Path]:
    with tempfile.TemporaryDirectory(prefix="snakebot.sim-campaign-") as tmp:
        yield Path(tmp)


def rig(board: str, workdir: Path, ram: RamMap) -> Rig:
    return Rig(board, FaultConfig(seed=1), workdir, ram=ram)


def test_the_map_is_read_from_the_elf_that_made_the_image(board: str, ram: RamMap):
    image = TARGETS[board].image.read_bytes()
    for address, data in ram.flash:
        offset = address - IMAGE_BASE[board]
        assert image[offset : offset + len(data)] == data
    assert 0x20000000 <= ram.ticks_ms < ram.ctl < 0x20002000


def test_a_true_map_passes_and_keeps_passing(board: str, ram: RamMap, workdir: Path):
    with rig(board, workdir, ram) as r:
        assert r.upload(gait_table()) == UploadResult.OK  # table view checked
        r.check_view()
        r.check_alive()
        assert r.health.reboots == 0


def test_a_counter_that_is_no_uptime_is_caught_at_start(board: str, ram: RamMap, workdir: Path):
    # The reset vector: a flash address, 134 million "ms", as CI once read at ticks_ms.
    wrong = dataclasses.replace(ram, ticks_ms=ram.flash[0][0] + 4)
    label = TARGETS[board].label
    with pytest.raises(CampaignFailed, match=rf"ticks_ms at 0x8003004 reads \d+ ms, but {label}"):
        rig(board, workdir, wrong).__enter__()


def test_a_counter_that_stands_still_is_caught_at_start(board: str, ram: RamMap, workdir: Path):
    wrong = dataclasses.replace(ram, ticks_ms=ram.busport_stats + 2)  # Bus Timeouts: 0
    with pytest.raises(CampaignFailed, match="stayed at 0 for"):
        rig(board, workdir, wrong).__enter__()


def test_an_elf_from_another_build_is_caught_at_start(board: str, ram: RamMap, workdir: Path):
    (address, data), *rest = ram.flash
    changed = data[:100] + bytes([data[100] ^ 1]) + data[101:]
    wrong = dataclasses.replace(ram, flash=((address, changed), *rest))
    with pytest.raises(CampaignFailed, match=f"flash at {address + 100:#x} differs"):
        rig(board, workdir, wrong).__enter__()


def test_a_wrong_table_layout_is_caught_at_the_first_commit(board: str, ram: RamMap, workdir: Path):
    wrong = dataclasses.replace(ram, active_len_offset=ram.active_len_offset + 2)
    with rig(board, workdir, wrong) as r:
        with pytest.raises(CampaignFailed, match="right after the commit the firmware reports"):
            r.upload(gait_table())


def test_a_machine_that_is_not_this_rigs_is_caught(
    board: str, ram: RamMap, workdir: Path, tmp_path: Path
):
    if board == "qemu":  # another QEMU's monitor answers
        with rig(board, workdir, ram) as r, rig(board, tmp_path, ram) as other:
            mine, r.target.fw = r.target.fw, other.target.fw
            try:
                with pytest.raises(CampaignFailed, match="answered 'snakebot-campaign-"):
                    r.check_view()
            finally:
                r.target.fw = mine
        return
    with rig(board, workdir, ram) as r:  # the emulated chip's thread has ended
        r.target.fw.stop()
        with pytest.raises(CampaignFailed, match="CM-530 is not running .its thread ended"):
            r.check_view()


def reset(r: Rig) -> None:
    """The machine's reset: QEMU's system reset (the stub runs again, then the
    application), the CM-530's reset button (the application starts again)."""
    if r.target.board == "qemu":
        r.target.fw.system_reset()
        return
    with r.lock:
        r.target.fw.board.mcu.reset("pin")


def test_a_real_reboot_is_counted_with_the_cpu_and_the_log(board: str, ram: RamMap, workdir: Path):
    with rig(board, workdir, ram) as r:
        time.sleep(0.5)  # an uptime that a fresh start takes a while to reach again
        r.check_alive()
        reset(r)
        # on the CM-530 the PING sent while it starts is lost and sent again after its
        # wide margin: its uptime is past the last look's by then, its reset count is not
        r.check_alive()
        assert r.health.reboots == 1
        (detail,) = r.health.reboot_details
        assert "started again (uptime " in detail and f"{r.target.label}'s log:" in detail
        assert "PC 080" in detail and "SP 200" in detail
        if board == "cm530":
            assert "resets pin at" in detail


@pytest.mark.parametrize("board", ["cm530"], indirect=True)  # QEMU does not model the IWDG
def test_a_starved_watchdog_fails_the_alive_check(board: str, ram: RamMap, workdir: Path):
    with rig(board, workdir, ram) as r:
        time.sleep(0.3)
        r.check_alive()
        healthy = Outcome("starved", 1, "")
        watchdog_checks(r, healthy)
        assert healthy.checks == {"alive": True} and healthy.counts["watchdog_feeds"] > 0
        with r.lock:  # a reload that lasts 0.1 ms: the firmware's next feed is too late
            r.target.fw.board.mcu.iwdg.rlr = 0
        deadline = time.monotonic() + 5
        while not r.target.watchdog().resets and time.monotonic() < deadline:
            time.sleep(0.05)
        r.check_alive()
        starved = Outcome("starved", 1, "")
        watchdog_checks(r, starved)
    assert r.health.reboots == 1
    assert starved.checks == {"alive": False} and starved.counts["watchdog_resets"] == 1
    (problem,) = starved.problems
    assert problem.startswith("alive: the watchdog reset the chip (at ")


@pytest.mark.parametrize("board", ["cm530"], indirect=True)  # the rig's own logic: one board
def test_bytes_the_firmware_never_heard_are_the_rig_failing(
    board: str, ram: RamMap, workdir: Path, monkeypatch: pytest.MonkeyPatch
):
    # as when the emulated CM-530 stopped reading its bus (two replies on their way at once)
    with rig(board, workdir, ram) as r:
        monkeypatch.setattr(r.bus, "master_in_waiting", lambda: 7)
        with pytest.raises(CampaignFailed, match="7 bytes the servos sent never reached"):
            r.freeze()


def test_the_command_line_says_the_view_is_wrong_and_exits_2(
    board: str,
    ram: RamMap,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
):
    wrong = dataclasses.replace(ram, ticks_ms=ram.flash[0][0] + 4)
    monkeypatch.setattr(RamMap, "from_build", classmethod(lambda cls, elf: wrong))
    assert campaigns.main(["--only", "clean", "--board", board]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: ticks_ms at ")
    assert "make firmware" in err[0]
