"""The CM-530 app's flash writes (firmware/app/store.c, store_play.c) with the controller
core, built for the host on the flash register model at the board's real addresses: a
committed 32 KB table is saved a step per tick and is what the next start finds; a save
overtaken by an upload that displaces the table, or by a table made active without a
commit, ends without touching the stored table; a 32 KB library store runs a step per
tick too, shown by Store State, and neither write lets a library operation abandon or
disturb the other. (store_load and a library play use blobs where they lie in
memory-mapped flash, which the host cannot map: a start is the store's own lookup here,
and plays are only ever refused.)"""

from __future__ import annotations

import random
import zlib

import pytest
from firmware_support import RegisterModels, board_value, build_hal_on_models
from flash_model import PowerCutModel

from snakebot.formats.gaittable import GaitTable, max_frames
from snakebot.formats.protocol import PacketParser, read, write
from snakebot.link.controller import chunk_writes, commit_write, load

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
bool store_save_step(ctl_device *ctl);
void store_play_init(ctl_device *ctl);
extern "Python+C" uint8_t board_buttons(void);
extern "Python+C" void board_leds(uint8_t on);
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
CTL_ID = CTL.default_id


@pytest.fixture(scope="module")
def app(tmp_path_factory):
    module = build_hal_on_models(
        "_store_app_host",
        [
            "hal_flash.c",
            "hal_iwdg.c",
            "../app/store.c",
            "../app/store_slots.c",
            "../app/store_lib.c",
            "../app/store_play.c",
            *(f"../core/{c}" for c in CORE),
        ],
        ["store.h", "store_slots.h", "store_play.h"],
        CDEF,
        tmp_path_factory.mktemp("store_app"),
        MODELS,
        defines=[("HAL_FLASH_BUSY_POLLS", "500")],
        include_dirs=["app", "core", "boards/cm530", "boards"],
        io16=True,
    )
    # the robot's panel, which these tests do not press (store_play_tick is not run)
    module.ffi.def_extern("board_buttons")(lambda: 0)
    module.ffi.def_extern("board_leds")(lambda on: None)
    return module


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
        app.lib.store_play_init(self.d)

    def send(self, packet: bytes) -> tuple[int, bytes]:
        """One instruction packet through the PC link: the reply's error byte and params."""
        out = self.app.ffi.new("uint8_t[]", 256)
        params = packet[5:-1]
        with MODELS.use(self.model):  # a READ of the Library page reads the directory
            n = self.app.lib.ctl_handle_packet(
                self.d, packet[2], packet[4], params, len(params), 0, out, 256
            )
        (reply,) = PacketParser().feed(bytes(self.app.ffi.buffer(out, n)))
        return reply.code, reply.params

    def _show(self, name: str):
        """The register `name`, its page shown in the window if it is on one."""
        page = CTL.page_number(name)
        if page is not None:
            assert self.set("Window Page", page) == 0
        return CTL.register(name)

    def get(self, name: str) -> int:
        reg = self._show(name)
        error, params = self.send(read(CTL_ID, reg.address, reg.size))
        assert error == 0
        return reg.decode(params)

    def set(self, name: str, value: int) -> int:
        reg = self._show(name) if name != "Window Page" else CTL.register(name)
        return self.send(write(CTL_ID, reg.address, value.to_bytes(reg.size, "little")))[0]

    def stage(self, blob: bytes) -> int:
        """WRITE blob's chunks: the first refused chunk's error, else 0."""
        for address, data in chunk_writes(blob, controller=CTL):
            error = self.send(write(CTL_ID, address, data))[0]
            if error:
                return error
        return 0

    def commit(self, blob: bytes, what: str) -> int:
        """Commit the staged blob as `what`: Upload Result."""
        assert self.send(write(CTL_ID, *commit_write(blob, CTL, what=what)))[0] == 0
        return self.get("Upload Result")

    def store(self, slot: int, blob: bytes) -> int:
        """LIBRARY_STORE blob as a table in `slot` (staged first): Upload Result."""
        assert self.set("Library Slot", slot) == 0
        assert self.stage(blob) == 0
        return self.commit(blob, "LIBRARY_STORE")

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


def table(seed: int, size: int = CAPACITY) -> bytes:
    """A table of 4 joints, as many frames as `size` bytes hold."""
    rng = random.Random(seed)
    frames = [[rng.randrange(250, 750) for _ in range(4)] for _ in range(max_frames(4, size))]
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


def result(name: str) -> int:
    return CTL.enums["Upload Result"][name]


STORE_STATE = CTL.enums["Store State"]


def test_a_32_kb_library_store_runs_over_ticks_and_shows_its_progress(app):
    board = Board(app)
    walk = table(5)
    assert board.store(6, walk) == result("LIBRARY_STORING")
    assert board.get("Store State") == STORE_STATE["LIBRARY"]
    progress = [board.get("Store Progress")]
    ticks, step = 0, 20
    while step == 20:
        step = board.ticks(20)
        ticks += step
        if step == 20:  # still under way
            progress.append(board.get("Store Progress"))
        if ticks == 100:  # meanwhile a play, another store, a commit: all wait
            assert board.set("Command", CTL.enums["Command"]["LIBRARY_PLAY"]) == 0
            assert board.get("Library Result") == result("STORE_BUSY")
            assert board.stage(table(6)) != 0
            assert board.get("Upload Result") == result("STORE_BUSY")
    assert 200 < ticks < 400  # a bounded step a tick, not all at once
    assert progress == sorted(progress) and progress[0] < 10 < 90 < progress[-1]
    assert board.get("Store State") == STORE_STATE["IDLE"]
    assert board.get("Store Progress") == 0
    # the store's outcome is in Library Result (Upload Result tells of the refused chunk)
    assert board.get("Library Result") == result("OK")
    assert board.get("Upload Result") == result("STORE_BUSY")
    assert board.get("Library Slot") == 6
    assert board.get("Slot Status") == CTL.enums["Slot Status"]["OK"]
    assert board.get("Slot CRC") == zlib.crc32(walk) and board.get("Slot Length") == len(walk)
    assert board.stored() == b""  # the committed table's store is not the library


def test_a_library_store_asked_during_the_table_save_waits_for_it(app):
    """Refused with STORE_BUSY while the committed table is saved, taken once the save has
    ended; a play likewise. (Tables of a quarter of the capacity, so that staging the
    library's blob does not land on the table being saved: an upload that does drops
    that table and ends its save, which is why `snakebot library store` waits for Store
    State IDLE before it stages anything.)"""
    board = Board(app)
    committed, walk = table(1, CAPACITY // 4), table(2, CAPACITY // 4)
    assert board.stage(committed) == 0
    assert board.commit(committed, "TABLE") == result("OK")
    assert app.lib.ctl_table_changed(board.d)
    with MODELS.use(board.model):
        app.lib.store_save_begin(board.d)
    board.ticks(20)
    assert board.get("Store State") == STORE_STATE["TABLE"]
    assert 0 < board.get("Store Progress") < 100
    assert board.set("Library Slot", 2) == 0
    assert board.stage(walk) == 0
    assert board.commit(walk, "LIBRARY_STORE") == result("STORE_BUSY")
    assert board.set("Command", CTL.enums["Command"]["LIBRARY_PLAY"]) == 0
    assert board.get("Library Result") == result("STORE_BUSY")
    board.ticks()
    assert board.stored() == committed  # the save was not abandoned
    assert board.get("Store State") == STORE_STATE["IDLE"]
    assert board.commit(walk, "LIBRARY_STORE") == result("LIBRARY_STORING")
    board.ticks()
    assert board.get("Library Result") == result("OK")
    assert board.get("Slot CRC") == zlib.crc32(walk)
    assert board.stored() == committed


def test_a_table_made_active_during_a_library_store_is_saved_after_it(app):
    """The core refuses commits while a library store runs; should a table still become
    active meanwhile (here: directly), the app saves it once the store has ended rather
    than dropping the save."""
    board = Board(app)
    walk, committed = table(7, CAPACITY // 4), table(8, CAPACITY // 4)
    assert board.store(1, walk) == result("LIBRARY_STORING")
    board.ticks(10)
    board.make_active(committed)  # as a commit would: the app is told to save it
    assert board.get("Store State") == STORE_STATE["LIBRARY"]
    board.ticks()
    assert board.get("Library Result") == result("OK")
    assert board.get("Slot CRC") == zlib.crc32(walk)
    assert board.stored() == committed
