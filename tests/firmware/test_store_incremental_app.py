"""The CM-530 app's table persistence (firmware/app/store.c) with the controller core,
built for the host on the flash register model at the board's real store address: a
committed 32 KB table is saved a step per tick and is what the next start finds; a save
overtaken by an upload that displaces the table, or by a table made active without a
commit, ends without touching the stored table. (store_load itself uses the table where
it lies in memory-mapped flash, which the host cannot map: a start is the store's own
lookup here.)"""

from __future__ import annotations

import random
import zlib

import pytest
from firmware_support import RegisterModels, board_value, build_hal_on_models
from flash_model import PowerCutModel

from snakebot.controller import load
from snakebot.gaittable import GaitTable, max_frames

CDEF = """
typedef struct ctl_device ctl_device;
size_t ctl_device_bytes(size_t arena);
void ctl_init(ctl_device *d);
void ctl_set_tables(ctl_device *d, size_t arena, uint16_t capacity);
bool ctl_load_table(ctl_device *d, const uint8_t *table, size_t len);
bool ctl_table_changed(ctl_device *d);
const uint8_t *ctl_active_table(const ctl_device *d, size_t *len);
size_t ctl_handle_packet(ctl_device *d, uint8_t id, uint8_t instruction, const uint8_t *params,
                         size_t nparams, uint32_t now_ms, uint8_t *out, size_t cap);
typedef struct { uint32_t base; uint32_t size; uint32_t page_size; } hal_flash_region_t;
typedef struct { uint32_t offset; uint32_t len; uint32_t seq; } store_record_t;
bool store_slots_newest(const hal_flash_region_t *r, store_record_t *out);
void store_save_begin(const ctl_device *ctl);
bool store_save_step(const ctl_device *ctl);
"""
CORE = sorted(p.name for p in (board_value.__globals__["FIRMWARE"] / "core").glob("*.c"))
MODELS = RegisterModels()
CAPACITY = board_value("cm530", "BOARD_TABLE_CAPACITY")
ARENA = board_value("cm530", "BOARD_TABLE_ARENA")
STORE = board_value("cm530", "BOARD_STORE_BASE")
STORE_SIZE = board_value("cm530", "BOARD_STORE_SIZE")
FLASH_END = board_value("cm530", "BOARD_LIMITS_STORE_BASE") + board_value(
    "cm530", "BOARD_LIMITS_STORE_SIZE"
)
CTL = load()
WRITE = 3


@pytest.fixture(scope="module")
def app(tmp_path_factory):
    return build_hal_on_models(
        "_store_app_host",
        [
            "hal_flash.c",
            "hal_iwdg.c",
            "../app/store.c",
            "../app/store_slots.c",
            "../app/store_lib.c",
            *(f"../core/{c}" for c in CORE),
        ],
        ["store.h", "store_slots.h"],
        CDEF,
        tmp_path_factory.mktemp("store_app"),
        MODELS,
        defines=[("HAL_FLASH_BUSY_POLLS", "500")],
        include_dirs=["app", "core", "boards/cm530"],
        io16=True,
    )


class Board:
    """A controller with the CM-530's arena, and its flash (the model) from the table
    store to the end of the limits' store."""

    def __init__(self, app) -> None:
        self.app = app
        self.model = PowerCutModel(b"\xa5" * (FLASH_END - STORE), base=STORE)
        self._mem = app.ffi.new("uint8_t[]", app.lib.ctl_device_bytes(ARENA))
        self.d = app.ffi.cast("ctl_device *", self._mem)
        app.lib.ctl_init(self.d)
        app.lib.ctl_set_tables(self.d, ARENA, CAPACITY)

    def active(self) -> bytes:
        n = self.app.ffi.new("size_t *")
        p = self.app.lib.ctl_active_table(self.d, n)
        return b"" if p == self.app.ffi.NULL else bytes(self.app.ffi.buffer(p, n[0]))

    def make_active(self, table: bytes) -> None:
        """A table made active as a commit does: the app is told to persist it."""
        assert self.app.lib.ctl_load_table(self.d, table, len(table))
        if self.app.lib.ctl_table_changed(self.d):
            with MODELS.use(self.model):
                self.app.lib.store_save_begin(self.d)

    def ticks(self, n: int | None = None) -> int:
        """Run the save a step per tick (n ticks, or to its end); the ticks run."""
        count = 0
        with MODELS.use(self.model):
            while (n is None or count < n) and self.app.lib.store_save_step(self.d):
                count += 1
        assert self.model.unexpected == []
        return count

    def stored(self) -> bytes:
        """The table a start would load: the store's newest record."""
        r = self.app.ffi.new("hal_flash_region_t *")
        r.base, r.size, r.page_size = (
            STORE,
            STORE_SIZE,
            board_value("cm530", "BOARD_FLASH_PAGE_SIZE"),
        )
        rec = self.app.ffi.new("store_record_t *")
        with MODELS.use(self.model):
            if not self.app.lib.store_slots_newest(r, rec):
                return b""
        return bytes(self.model.mem[rec.offset : rec.offset + rec.len])


def table(seed: int) -> bytes:
    rng = random.Random(seed)
    frames = [[rng.randrange(250, 750) for _ in range(4)] for _ in range(max_frames(4, CAPACITY))]
    return GaitTable((1, 2, 3, 4), 20, True, ((250, 750),) * 4, frames).encode()


def test_a_committed_32_kb_table_is_saved_over_ticks_and_loads_at_the_next_start(app):
    board = Board(app)
    first = table(1)
    assert len(first) == CAPACITY
    board.make_active(first)
    ticks = board.ticks()
    assert 200 < ticks < 400  # a bounded step a tick, not all at once
    assert board.stored() == first
    second = table(2)
    board.make_active(second)
    board.ticks()
    assert board.stored() == second


def saving_over(app, ticks: int) -> Board:
    """A board that stored table 1 and is `ticks` ticks into saving table 2."""
    board = Board(app)
    board.make_active(table(1))
    board.ticks()
    board.make_active(table(2))
    board.ticks(ticks)
    return board


def test_a_save_overtaken_by_an_upload_over_the_table_keeps_the_stored_one(app):
    board = saving_over(app, 10)  # erasing the slot still
    # a chunk of a new upload lands on the (stopped) table and displaces it
    offset = CTL.register("Upload Offset")
    params = bytes([offset.address]) + offset.encode(0) + bytes(16)
    out = app.ffi.new("uint8_t[]", 250)
    app.lib.ctl_handle_packet(board.d, 200, WRITE, params, len(params), 0, out, 250)
    assert board.active() == b""
    assert board.ticks() == 0  # the save ended at once
    assert board.stored() == table(1)


def test_a_save_overtaken_by_a_table_made_active_without_commit_keeps_the_stored_one(app):
    board = saving_over(app, 100)  # programming
    # as LIBRARY_PLAY does: another table of the same size, nothing to persist
    third = table(3)
    assert app.lib.ctl_load_table(board.d, third, len(third))
    board.ticks()
    assert board.stored() == table(1)
    assert zlib.crc32(board.active()) == zlib.crc32(third)
