"""Build script for ``snakebot._core``: the portable C core, compiled for the host.

Every ``firmware/core/*.c`` is compiled in, and every ``firmware/core/*.h`` may publish
part of itself to Python by fencing plain declarations between ``/* cffi:begin */`` and
``/* cffi:end */``. The cdef is therefore read from the very headers the firmware
compiles against, so the two builds cannot drift apart.
"""

from __future__ import annotations

import re
from pathlib import Path

from cffi import FFI

CORE_DIR = Path(__file__).resolve().parents[2] / "firmware" / "core"
SIM_DIR = Path(__file__).resolve().parent / "sim" / "csrc"
"""Host-only C of the emulator (never in the firmware), published the same way."""
FENCE = re.compile(r"/\* cffi:begin \*/(.*?)/\* cffi:end \*/", re.S)
BOARDS_DIR = CORE_DIR.parent / "boards"
"""One directory per board (``board.h``): the facts the host needs of each are published
as ``BOARD_<NAME>_<FACT>`` (``board_facts``)."""
BOARD_FACTS = (
    "TABLE_CAPACITY",
    "CONTROL_TICK_MS",
    "PC_BAUD",
    "APP_BASE",
    "HSE_HZ",
    "WATCHDOG_MS",
    "FLASH_PAGE_SIZE",
)
"""The ``BOARD_*`` numbers of each board published to Python, each a plain literal (decimal
or hexadecimal) in its board.h or a header of the board that board.h includes."""


def published_declarations(header: Path) -> str:
    """The cffi-visible part of one header (empty if it publishes nothing)."""
    return "\n".join(block.strip() for block in FENCE.findall(header.read_text()))


def board_facts() -> str:
    """``#define BOARD_<NAME>_<FACT> <value>`` for every board and fact in BOARD_FACTS,
    read from the board's board.h: the host cannot include a board.h (it names the
    hardware, and every board's defines the same names), so the literal is carried over
    here, at build time, from the one place it is written."""
    out = []
    for board in sorted(p for p in BOARDS_DIR.iterdir() if (p / "board.h").is_file()):
        text = _board_text(board / "board.h")
        for fact in BOARD_FACTS:
            found = re.search(rf"^#define BOARD_{fact} (0x[0-9A-Fa-f]+|\d+)U?L?\s*$", text, re.M)
            if found is None:
                raise SystemExit(f"{board / 'board.h'}: BOARD_{fact} is not a plain number")
            out.append(f"#define BOARD_{board.name.upper()}_{fact} {int(found[1], 0)}")
    return "\n".join(out)


def _board_text(header: Path) -> str:
    """A board header with the board's own headers it includes (``#include "x.h"`` found
    beside it), so a fact may sit in the header that holds its peripheral's set-up."""
    text = header.read_text()
    for name in re.findall(r'^#include "([^"]+)"', text, re.M):
        included = header.parent / name
        if included.is_file() and BOARDS_DIR in included.resolve().parents:
            text += "\n" + _board_text(included)
    return text


def _relative(path: Path) -> str:
    # setuptools insists on paths relative to the project root.
    return str(path.relative_to(CORE_DIR.parents[1]))


headers = sorted(CORE_DIR.glob("*.h")) + sorted(SIM_DIR.glob("*.h"))
sources = sorted(CORE_DIR.glob("*.c")) + sorted(SIM_DIR.glob("*.c"))

ffibuilder = FFI()
BOARD_DEFINES = board_facts()
ffibuilder.cdef("\n".join(filter(None, (published_declarations(h) for h in headers))))
# the values come from the source below; cffi checks the C side has each name
ffibuilder.cdef(re.sub(r"^(#define \w+) .*$", r"\1 ...", BOARD_DEFINES, flags=re.M))
ffibuilder.set_source(
    "snakebot._core",
    "\n".join([*(f'#include "{h.name}"' for h in headers), BOARD_DEFINES]),
    sources=[_relative(s) for s in sources],
    include_dirs=[_relative(CORE_DIR), _relative(SIM_DIR)],
    # -O3 for the kinematics' small fixed loops; -fno-math-errno lets sqrt be one
    # instruction (errno is never read). No -march: the module must run on any x86-64;
    # KIN_TRIG_DISPATCH lets the batch sine (kin_trig.c) use AVX2 where the CPU has it.
    extra_compile_args=[
        "-std=c99",
        "-O3",
        "-fno-math-errno",
        "-DKIN_TRIG_DISPATCH",
        "-Wall",
        "-Wextra",
        "-Wno-unused-parameter",
    ],
    libraries=["m"],
)

if __name__ == "__main__":
    ffibuilder.compile(verbose=True)
