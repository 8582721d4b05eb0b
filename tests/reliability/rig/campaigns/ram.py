"""Where the firmware keeps what the campaigns read back from its RAM: the addresses of the
board's ELF symbols, and the layout of ``ctl_device`` (the same core on every board)."""

from __future__ import annotations

import functools
import subprocess
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from elftools.common.exceptions import ELFError
from elftools.elf.elffile import ELFFile

from snakebot.sim.errors import SimFailure
from tests.reliability.rig.campaigns.testbed import CORE_DIR, REBUILD, CampaignFailed


@dataclass(frozen=True)
class RamMap:
    """Where the firmware keeps what the campaigns read back: from the symbol table of the
    ELF the board's image was made from (``build/qemu/firmware.elf``,
    ``build/cm530/firmware.elf``), and a probe compiled for the Cortex-M3 for the layout
    of ``ctl_device``. ``flash`` holds what that ELF loads into flash (address, bytes), so
    a rig can check that the machine runs this very build before it trusts an address
    (:meth:`Rig.check_view`)."""

    ticks_ms: int
    busport_stats: int
    pclink_stats: int
    ctl: int
    ctl_size: int
    active_offset: int
    active_len_offset: int
    flash: tuple[tuple[int, bytes], ...] = ()
    source: str = ""

    @classmethod
    def from_build(cls, elf_file: Path) -> RamMap:
        try:
            with elf_file.open("rb") as f:
                elf = ELFFile(f)
                found = _objects(elf)
                flash = tuple(
                    (seg["p_paddr"], seg.data())
                    for seg in elf.iter_segments()
                    if seg["p_type"] == "PT_LOAD" and seg["p_filesz"] > 0
                )
        except (OSError, ELFError) as exc:
            raise CampaignFailed(f"cannot read {elf_file} ({exc}): {REBUILD}") from None

        def where(name: str, source: str) -> tuple[int, int]:
            try:
                return found[(name, source)]
            except KeyError:
                raise CampaignFailed(f"{name} ({source}) is not in {elf_file}: {REBUILD}") from None

        ctl, ctl_size = where("ctl", "main.c")  # the device, then its table arena
        active, active_len, size = _ctl_layout()
        if size > ctl_size:
            raise CampaignFailed(
                f"ctl_device is {size} bytes in the probe, {ctl_size} in {elf_file}: {REBUILD}"
            )
        return cls(
            ticks_ms=where("ticks_ms", "hal_systick.c")[0],
            busport_stats=where("stats", "busport.c")[0],
            pclink_stats=where("stats", "pclink.c")[0],
            ctl=ctl,
            ctl_size=ctl_size,
            active_offset=active,
            active_len_offset=active_len,
            flash=flash,
            source=str(elf_file),
        )


def _objects(elf: ELFFile) -> dict[tuple[str, str], tuple[int, int]]:
    """(name, source file) -> (address, size) of the ELF's data objects. A file's static
    objects follow its STT_FILE symbol in the table; globals come after every file's
    locals, so they are keyed by no file."""
    symtab = elf.get_section_by_name(".symtab")
    if symtab is None:
        raise ELFError("no symbol table (stripped?)")
    found: dict[tuple[str, str], tuple[int, int]] = {}
    source = ""
    for sym in symtab.iter_symbols():
        kind, bind = sym["st_info"]["type"], sym["st_info"]["bind"]
        if kind == "STT_FILE":
            source = sym.name
        elif kind == "STT_OBJECT":
            found[(sym.name, source if bind == "STB_LOCAL" else "")] = (
                sym["st_value"],
                sym["st_size"],
            )
    return found


@functools.cache
def _ctl_layout() -> tuple[int, int, int]:
    """offsetof(ctl_device, active), offsetof(..., active_len), sizeof(ctl_device) on the
    Cortex-M3, from a probe compiled with the firmware's compiler (once a process: the
    same core on every board)."""
    source = (
        '#include <stddef.h>\n#include "ctl_device.h"\n'
        "const unsigned int snakebot_probe[3] = {offsetof(ctl_device, active), "
        "offsetof(ctl_device, active_len), sizeof(ctl_device)};\n"
    )
    with tempfile.TemporaryDirectory(prefix="snakebot.sim-probe-") as tmp:
        c, o, b = (Path(tmp) / n for n in ("probe.c", "probe.o", "probe.bin"))
        c.write_text(source)
        try:
            subprocess.run(
                [
                    "arm-none-eabi-gcc",
                    "-mcpu=cortex-m3",
                    "-mthumb",
                    "-std=c99",
                    "-Os",
                    f"-I{CORE_DIR}",
                    "-c",
                    str(c),
                    "-o",
                    str(o),
                ],
                check=True,
                capture_output=True,
                text=True,
            )
            subprocess.run(
                ["arm-none-eabi-objcopy", "-O", "binary", "-j", ".rodata", str(o), str(b)],
                check=True,
                capture_output=True,
                text=True,
            )
        except (OSError, subprocess.CalledProcessError) as exc:
            raise SimFailure(
                f"cannot compile the layout probe with arm-none-eabi-gcc ({exc}): run `make setup`"
            ) from exc
        words = np.frombuffer(b.read_bytes()[:12], "<u4")
        return int(words[0]), int(words[1]), int(words[2])
