"""Flash and RAM of the firmware images, against the qemu board's goal (32 KB flash, 8 KB
RAM) and the CM-530's capacity. Prints one line per board; ratio < 1.0 means within.

    .venv/bin/python bench/bench_firmware_size.py      (after `make firmware`)
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
FLASH_PARTS = (".isr_vector", ".text", ".ARM.exidx", ".data")
RAM_PARTS = (".data", ".bss", ".stack")
# board: (flash reference, RAM reference, what the reference is)
REFERENCES = {
    "qemu": (32 * 1024, 8 * 1024, "goal"),
    "cm530": (468 * 1024, 64 * 1024, "capacity"),
}


def section_sizes(elf: Path) -> dict[str, int]:
    out = subprocess.run(
        ["arm-none-eabi-size", "-A", "-d", str(elf)], capture_output=True, text=True, check=True
    ).stdout
    sizes = {}
    for line in out.splitlines():
        parts = line.split()
        if len(parts) == 3 and parts[0].startswith("."):
            sizes[parts[0]] = int(parts[1])
    return sizes


def main() -> int:
    for board, (flash_ref, ram_ref, what) in REFERENCES.items():
        elf = ROOT / "build" / board / "firmware.elf"
        if not elf.exists():
            print(f"{elf} missing: run `make firmware` first", file=sys.stderr)
            return 2
        s = section_sizes(elf)
        flash = sum(s.get(k, 0) for k in FLASH_PARTS)
        ram = sum(s.get(k, 0) for k in RAM_PARTS)
        print(
            f"{board:6s} flash {flash:6d} B = {flash / flash_ref:.3f} x {what} ({flash_ref} B); "
            f"RAM {ram:5d} B = {ram / ram_ref:.3f} x {what} ({ram_ref} B)"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
