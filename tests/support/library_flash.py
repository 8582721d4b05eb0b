"""The gait library's flash store (firmware/app/store_lib.c) built for the host on the
flash register model, with a small library laid out in it (a directory of two pages and
nine one-page areas), for its tests and the power-cut campaign
(tests/reliability/rig/campaigns/): what a fresh start finds in each slot, and running
a store or delete with the power cut at a chosen flash operation."""

from __future__ import annotations

import random
from pathlib import Path
from typing import Any

from firmware_support import RegisterModels, build_hal_on_models
from flash_model import BASE, PAGE, PowerCutModel

SLOTS, NAME_MAX = 8, 16
DIR_PAGES, AREA_PAGES = 2, 1
AREAS = SLOTS + 1
SIZE = PAGE * (DIR_PAGES + AREAS * AREA_PAGES)
OK, EMPTY, DAMAGED, BAD_SLOT, BAD_BLOB, FLASH = range(6)
TABLE, PROGRAM = 1, 2

ENTRY_BYTES = 8 + NAME_MAX  # kind, area, length, CRC-32, name

CDEF = f"""
typedef struct {{ uint32_t base; uint32_t size; uint32_t page_size; }} hal_flash_region_t;
typedef struct {{ hal_flash_region_t dir; hal_flash_region_t areas; uint32_t area_size; }}
    store_lib_t;
typedef struct {{
    uint8_t kind; uint16_t len; uint32_t crc; uint32_t addr; uint8_t name[{NAME_MAX}];
}} store_lib_entry_t;
uint32_t store_lib_capacity(const store_lib_t *lib);
int store_lib_entry(const store_lib_t *lib, uint8_t slot, store_lib_entry_t *out);
int store_lib_put(const store_lib_t *lib, uint8_t slot, uint8_t kind, const uint8_t *name,
                  const uint8_t *data, uint32_t len);
int store_lib_delete(const store_lib_t *lib, uint8_t slot);
typedef struct {{
    const hal_flash_region_t *r;
    const uint8_t *data;
    uint32_t len, slot, seq, done, expect, crc;
    uint8_t phase, status, bare;
}} store_slots_job_t;
typedef struct {{
    const store_lib_t *lib;
    store_slots_job_t write;
    uint8_t dir[{SLOTS * ENTRY_BYTES}];
    uint8_t stage;
    uint8_t status;
}} store_lib_job_t;
int store_lib_begin_put(store_lib_job_t *job, const store_lib_t *lib, uint8_t slot,
                        uint8_t kind, const uint8_t *name, const uint8_t *data, uint32_t len);
int store_lib_begin_delete(store_lib_job_t *job, const store_lib_t *lib, uint8_t slot);
bool store_lib_step(store_lib_job_t *job, uint32_t halfwords);
uint8_t store_lib_progress(const store_lib_job_t *job);
"""

MODELS = RegisterModels()

SOURCES = ["hal_flash.c", "../app/store_slots.c", "../app/store_lib.c", "../core/crc32.c"]
HEADERS = ["hal_flash.h", "store_lib.h"]
OPTIONS: dict[str, Any] = {
    "defines": [("HAL_FLASH_BUSY_POLLS", "500")],  # the firmware's is 2 000 000
    "include_dirs": ["app", "core"],
    "io16": True,
}


def build(tmpdir: Path) -> Any:
    """The store compiled for the host, answered by :data:`MODELS`."""
    return build_hal_on_models(
        "_hal_library_host", SOURCES, HEADERS, CDEF, tmpdir, MODELS, **OPTIONS
    )


ERASED_LONG_AGO = b"\xa5" * SIZE  # never-erased flash: no directory, no data


def lib(hal: Any) -> Any:
    """The library's layout as store_lib_t."""
    s = hal.ffi.new("store_lib_t *")
    s.dir.base, s.dir.size, s.dir.page_size = BASE, DIR_PAGES * PAGE, PAGE
    area = AREA_PAGES * PAGE
    s.areas.base, s.areas.size, s.areas.page_size = BASE + DIR_PAGES * PAGE, AREAS * area, PAGE
    s.area_size = area
    return s


Slot = tuple[int, bytes, bytes]  # kind, name, data


def contents(hal, mem: bytes, layout: Any = None) -> list[Slot | int]:
    """What a fresh start finds in each slot: (kind, name, data), or the status if none;
    in the library :func:`lib` lays out unless ``layout`` (a store_lib_t) is given."""
    out: list[Slot | int] = []
    layout = lib(hal) if layout is None else layout
    with MODELS.use(PowerCutModel(mem)) as m:
        e = hal.ffi.new("store_lib_entry_t *")
        for slot in range(SLOTS):
            st = hal.lib.store_lib_entry(layout, slot, e)
            if st != OK:
                out.append(st)
                continue
            at = e.addr - BASE
            name = bytes(hal.ffi.buffer(e.name)).rstrip(b"\0")
            out.append((e.kind, name, bytes(m.mem[at : at + e.len])))
        assert m.unexpected == []
    return out


def run(hal, mem: bytes, op, cut_at: int | None = None, seed: int = 0):
    """Run ``op(lib)`` on flash holding ``mem``: (status, flash after, flash operations)."""
    with MODELS.use(PowerCutModel(mem, cut_at, seed)) as m:
        status = op(lib(hal))
        assert m.unexpected == []
        return status, bytes(m.mem), m.ops


def put(hal, slot: int, kind: int, name: bytes, data: bytes):
    padded = name.ljust(NAME_MAX, b"\0")
    return lambda s: hal.lib.store_lib_put(
        s, slot, kind, hal.ffi.from_buffer(padded), hal.ffi.from_buffer(data), len(data)
    )


def delete(hal, slot: int):
    return lambda s: hal.lib.store_lib_delete(s, slot)


def blob(n: int, seed: int) -> bytes:
    rng = random.Random(seed)
    return bytes(rng.getrandbits(8) for _ in range(n))
