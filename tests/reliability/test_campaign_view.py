"""The fault campaigns' own view of the machine (``Rig.check_view`` in
tests/reliability/rig/campaigns/): what the rig reads from the firmware's RAM through
QEMU's monitor counts only once it is shown to be the running firmware's, so a wrong RAM
map, an ELF from another build, or another QEMU's monitor is reported as the rig failing
(``CampaignFailed``, exit 2), never as the firmware breaking a promise; and a real
reboot is reported with the CPU's PC and SP and QEMU's log."""

from __future__ import annotations

import dataclasses
import tempfile
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
from firmware_support import build_firmware

from snakebot.link.controller import UploadResult
from snakebot.sim.bus.faults import FaultConfig
from tests.reliability.rig import campaigns
from tests.reliability.rig.campaigns import CampaignFailed, RamMap, Rig, gait_table

pytestmark = [pytest.mark.qemu, pytest.mark.slow, pytest.mark.serial]


@pytest.fixture(scope="module")
def ram() -> RamMap:
    build_firmware()
    return RamMap.from_build()


@pytest.fixture
def workdir() -> Iterator[Path]:
    with tempfile.TemporaryDirectory(prefix="snakebot.sim-campaign-") as tmp:
        yield Path(tmp)


def test_the_map_is_read_from_the_elf_that_made_the_image(ram: RamMap):
    image = campaigns.IMAGE.read_bytes()
    for address, data in ram.flash:
        offset = address - 0x08000000  # the image is the whole flash from its start
        assert image[offset : offset + len(data)] == data
    assert 0x20000000 <= ram.ticks_ms < ram.ctl < 0x20002000


def test_a_true_map_passes_and_keeps_passing(ram: RamMap, workdir: Path):
    with Rig(FaultConfig(seed=1), workdir, ram=ram) as rig:
        assert rig.upload(gait_table()) == UploadResult.OK  # table view checked
        rig.check_view()
        rig.check_alive()
        assert rig.health.reboots == 0


def test_a_counter_that_is_no_uptime_is_caught_at_start(ram: RamMap, workdir: Path):
    # The reset vector: a flash address, 134 million "ms", as CI once read at ticks_ms.
    wrong = dataclasses.replace(ram, ticks_ms=ram.flash[0][0] + 4)
    with pytest.raises(CampaignFailed, match=r"ticks_ms at 0x8003004 reads \d+ ms, but QEMU"):
        Rig(FaultConfig(seed=1), workdir, ram=wrong).__enter__()


def test_a_counter_that_stands_still_is_caught_at_start(ram: RamMap, workdir: Path):
    wrong = dataclasses.replace(ram, ticks_ms=ram.busport_stats + 2)  # Bus Timeouts: 0
    with pytest.raises(CampaignFailed, match="stayed at 0 for"):
        Rig(FaultConfig(seed=1), workdir, ram=wrong).__enter__()


def test_an_elf_from_another_build_is_caught_at_start(ram: RamMap, workdir: Path):
    (address, data), *rest = ram.flash
    changed = data[:100] + bytes([data[100] ^ 1]) + data[101:]
    wrong = dataclasses.replace(ram, flash=((address, changed), *rest))
    with pytest.raises(CampaignFailed, match=f"flash at {address + 100:#x} differs"):
        Rig(FaultConfig(seed=1), workdir, ram=wrong).__enter__()


def test_a_wrong_table_layout_is_caught_at_the_first_commit(ram: RamMap, workdir: Path):
    wrong = dataclasses.replace(ram, active_len_offset=ram.active_len_offset + 2)
    with Rig(FaultConfig(seed=1), workdir, ram=wrong) as rig:
        with pytest.raises(CampaignFailed, match="right after the commit the firmware reports"):
            rig.upload(gait_table())


def test_another_qemus_monitor_is_caught(ram: RamMap, workdir: Path, tmp_path: Path):
    with (
        Rig(FaultConfig(seed=1), workdir, ram=ram) as rig,
        Rig(FaultConfig(seed=1), tmp_path, ram=ram) as other,
    ):
        rig.fw, mine = other.fw, rig.fw  # the rig now asks the other machine's monitor
        try:
            with pytest.raises(CampaignFailed, match="answered 'snakebot-campaign-"):
                rig.check_view()
        finally:
            rig.fw = mine


def test_a_real_reboot_is_counted_with_the_cpu_and_the_log(ram: RamMap, workdir: Path):
    with Rig(FaultConfig(seed=1), workdir, ram=ram) as rig:
        time.sleep(0.5)  # an uptime that a fresh start takes a while to reach again
        rig.check_alive()
        rig.fw.system_reset()  # the stub runs again, then the application from its start
        rig.check_alive()
        assert rig.health.reboots == 1
        (detail,) = rig.health.reboot_details
        assert "uptime went from" in detail and "QEMU log:" in detail
        assert "PC 080" in detail and "SP 200" in detail


def test_the_command_line_says_the_view_is_wrong_and_exits_2(
    ram: RamMap, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
):
    wrong = dataclasses.replace(ram, ticks_ms=ram.flash[0][0] + 4)
    monkeypatch.setattr(RamMap, "from_build", classmethod(lambda cls: wrong))
    assert campaigns.main(["--only", "clean"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: ticks_ms at ")
    assert "make firmware" in err[0]
