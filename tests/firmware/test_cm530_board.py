"""Board-level checks that only running the exact CM-530 image makes possible: it boots
from a cold reset and from every state the ROBOTIS bootloader may leave (the clock tests'
leftovers: the PLL running from HSE x6, USART3 armed with its interrupt pending, SysTick
running, PRIMASK set); the watchdog is never starved, a 32 KB library store included,
even with the LSI at the fast end of its range; and the stack stays inside what the linker
reserved for it."""

from __future__ import annotations

import struct
import subprocess
import time
from dataclasses import replace

import pytest
import serial
from controller_cli_support import SNAKE5_IDS, cli, cli_json, save, wave_table
from firmware_support import cm530_image

from snakebot.facts.boards import PC_LINK_BAUD, WATCHDOG_MS
from snakebot.firmware import image as firmware_image
from snakebot.model.robots import load_robot
from snakebot.sim.mcu.board import BUS_RX_ENABLE, Cm530, Leftovers
from snakebot.sim.mcu.runner import QUIET_AFTER_S, QUIET_STEP_S, STEP_S, McuFirmware
from snakebot.sim.options import SimOptions
from snakebot.sim.physics.select import make_world
from snakebot.sim.serve import EmulatedRobot

pytest.importorskip("unicorn")

ELF = firmware_image("cm530", "firmware.elf")
LSI_FASTEST_HZ = 60_000  # the datasheet's range is 30..60 kHz
STACK_PAINT = 0x5AC3A55A  # hal_startup.c paints free RAM with it
PING = bytes([0xFF, 0xFF, 200, 2, 1, (~(200 + 2 + 1)) & 0xFF])
PONG = bytes([0xFF, 0xFF, 200, 2, 0, (~(200 + 2)) & 0xFF])
SLOW_HOST = {"SNAKEBOT_MARGIN_MS": "3000"}  # the emulated board shares a loaded machine
WORLD_PERIOD_S = 0.01  # a world stepping every 10 ms


@pytest.fixture(scope="module")
def image() -> bytes:
    return cm530_image()


def symbols() -> dict[str, int]:
    out = subprocess.run(
        ["arm-none-eabi-nm", str(ELF)], capture_output=True, text=True, check=True
    ).stdout
    return {p[2]: int(p[0], 16) for p in (line.split() for line in out.splitlines()) if len(p) == 3}


@pytest.mark.parametrize(
    "left",
    [
        Leftovers(),
        Leftovers(pll=True),
        Leftovers(usart3_pending=True),
        Leftovers(systick=True),
        Leftovers(primask=True),
        Leftovers.every(),
    ],
    ids=["cold", "pll", "usart3-pending", "systick", "primask", "all"],
)
def test_boots_and_answers_from_every_bootloader_leftover(image, left):
    board = Cm530(image, leftovers=left)
    board.run_for(0.05)
    board.pc_out.clear()
    board.pc_send(PING)
    board.run_for(0.02)
    assert bytes(board.pc_out) == PONG
    m = board.mcu
    assert m.resets == []  # no fault, no watchdog: the first start was the only one
    assert m.rcc.clocks().sysclk == 72_000_000
    assert m.nvic.vtor == 0x0800_3000


def test_a_software_reset_boots_again_and_says_so(image):
    board = Cm530(image)
    board.run_for(0.05)
    assert board.mcu.systick.csr & 1  # the firmware's millisecond tick runs
    board.mcu.reset("software")
    assert board.mcu.systick.csr == 0  # a system reset stops it, as every peripheral
    board.run_for(0.05)
    board.pc_send(PING)
    board.run_for(0.02)
    assert bytes(board.pc_out).endswith(PONG)


def test_stack_high_water_mark_stays_in_the_reserved_stack(image):
    bus = replace(SimOptions.from_query(""), robot="snake5").build_bus()
    board = Cm530(image, bus=bus)
    board.run_for(0.5)
    syms = symbols()
    ebss, estack = syms["_ebss"], syms["_estack"]
    ram = board.mcu.read(ebss, estack - ebss)
    words = struct.unpack(f"<{len(ram) // 4}I", ram[: len(ram) // 4 * 4])
    untouched = next(i for i, w in enumerate(words) if w != STACK_PAINT)
    deepest = ebss + 4 * untouched
    used = estack - deepest
    reserved = estack - syms.get("__stack_size", 0) if "__stack_size" in syms else None
    assert board.mcu.cpu.lowest_sp >= deepest - 64  # the two measures agree
    assert used < 4096, f"the stack reached {used} bytes of the 4 KB cm530.ld reserves"
    assert reserved is None or deepest >= reserved


def test_frames_timed_in_c_leave_as_the_models_events_send_them(image):
    # the USARTs' frames end in C, inside the CPU's run and its sleeps: the firmware must
    # see the same chip as with the model's scheduled events, to the instruction
    runs = []
    for in_c in (True, False):
        board = Cm530(image, leftovers=Leftovers(pll=True))
        if not in_c:
            board.mcu.time_events_in_python()
        out: list[tuple[int, float]] = []
        board.mcu.usart3.on_tx = lambda b, s, e, baud, out=out: out.append((b, s))
        board.run_until(0.05)
        for k in range(20):  # PINGs, some while the answer before is still going out
            board.pc_send(PING)
            board.run_until(board.now() + (0.0004, 0.003)[k % 2])
        board.run_until(board.now() + 0.01)
        runs.append((out, board.mcu.cpu.count, board.mcu.cpu.sleeps, board.mcu.nvic.c.entries))
    (out, count, sleeps, entries), python = runs
    assert len(out) == 20 * len(PONG) and bytes(b for b, _ in out) == 20 * PONG
    assert (out, count, sleeps, entries) == python


def _pc_session(tmp_path) -> list[tuple[float, bytes]]:
    """What the PC sent, and when on the board's clock, to upload a wave and play it on
    `sim serve`'s cm530 board for a while."""
    sends: list[tuple[float, bytes]] = []
    with EmulatedRobot("snake5", board="cm530") as robot:
        with robot.lock:
            board = robot._mcu.board  # noqa: SLF001 - a tap on the PC link
            pc_send = board.pc_send
            board.pc_send = lambda data: (sends.append((board.now(), data)), pc_send(data))
        port = robot.info.pc_link
        cli_json("upload", save(wave_table(), tmp_path), "--port", port, env=SLOW_HOST)
        assert cli_json("play", "--port", port, env=SLOW_HOST)["state"] == "PLAYING"
        time.sleep(0.3)
        assert cli_json("stop", "--port", port, env=SLOW_HOST)["state"] == "IDLE"
    return sends


@pytest.mark.slow
@pytest.mark.serial  # the session is recorded in real time on a pty
def test_replies_and_ticks_timed_in_c_reach_the_firmware_as_the_models_events(image, tmp_path):
    # the servos' replies reach USART1's receiver in C (RXNE at each stop bit, PB5 looked
    # at then), SysTick steps to zero in C and GPIOB's pin writes are served in C: the
    # same session (a gait uploaded, played and stopped) must give the same bytes on the
    # bus at the same times, the same instruction count, sleeps and exception entries as
    # with the models' events and GPIOB's model (a listener takes every write there)
    sends = _pc_session(tmp_path)
    runs = []
    for in_c in (True, False):
        bus = replace(SimOptions.from_query(""), robot="snake5").build_bus()
        board = Cm530(image, bus=bus)
        turns: list[tuple[int, bool]] = []
        if not in_c:
            board.mcu.time_events_in_python()
            board.mcu.gpio["B"].listen(lambda pin, level, turns=turns: turns.append((pin, level)))
        out: list[tuple[int, float]] = []
        usart1 = board.mcu.usart1
        on_tx = usart1.on_tx
        usart1.on_tx = lambda b, s, e, baud, out=out, on_tx=on_tx: (
            out.append((b, s)),
            on_tx(b, s, e, baud),
        )
        for t, data in sends:
            board.run_until(t)
            board.pc_send(data)
        board.run_until(board.now() + 0.05)
        m = board.mcu
        runs.append(
            (
                out,
                bytes(board.pc_out),
                board.bus_stats,
                (usart1.received, usart1.overruns, m.systick.fired),
                (m.cpu.count, m.cpu.sleeps, m.nvic.c.entries),
            )
        )
    in_c, python = runs
    stats = in_c[2]
    assert stats.sent > 500 and stats.received > 300 and stats.blocked == 0
    assert turns.count((BUS_RX_ENABLE, True)) > 50  # the buffer turned for each reply
    assert in_c == python


def _on_a_board(
    image: bytes,
    sends: list[tuple[float, bytes]],
    *,
    in_runs: bool = True,
    world_steps_wait: bool = True,
) -> tuple[list[int], tuple]:
    """The PC's ``sends`` on a board with snake5's servos in a world: the sizes of the
    runs USART1's drains handed on at once, and what the board did: the bytes on the bus
    with their starts and ends, PC bytes, counts, servo positions, the world's samples,
    instruction count, sleeps and exception entries. ``in_runs`` False: a drain hands its
    bytes on one by one; ``world_steps_wait`` False: the board follows a world's steps."""
    bus = replace(SimOptions.from_query(""), robot="snake5").build_bus()
    world = make_world("kinematic", bus, load_robot("snake5"), period=WORLD_PERIOD_S)
    board = Cm530(image, bus=bus)
    board.world_steps_wait = world_steps_wait
    usart1 = board.mcu.usart1
    out: list[tuple[int, float, float]] = []
    sizes: list[int] = []
    on_tx, on_tx_run = usart1.on_tx, usart1.on_tx_run
    assert on_tx is not None and on_tx_run is not None

    def tap(b: int, s: float, e: float, baud: float) -> None:
        out.append((b, s, e))
        on_tx(b, s, e, baud)

    def tap_run(data: list[int], starts: list[float], frame: float, baud: float) -> None:
        sizes.append(len(data))
        out.extend((b, s, s + frame) for b, s in zip(data, starts, strict=True))
        on_tx_run(data, starts, frame, baud)

    if in_runs:
        usart1.hand_on_runs(tap, tap_run)
    else:
        usart1.on_tx = tap  # a drain hands its bytes on one by one
    for t, data in sends:
        board.run_until(t)
        board.pc_send(data)
    board.run_until(board.now() + 0.05)
    m, record = board.mcu, world.record()
    return sizes, (
        out,
        bytes(board.pc_out),
        board.bus_stats,
        bus.positions(),
        (record.t.tolist(), record.q.tolist()),
        (usart1.received, usart1.overruns, m.systick.fired),
        (m.cpu.count, m.cpu.sleeps, m.nvic.c.entries),
    )


@pytest.mark.slow
@pytest.mark.serial  # the session is recorded in real time on a pty
def test_a_drains_bytes_at_once_and_a_worlds_steps_left_to_the_bus_change_nothing(image, tmp_path):
    # the bytes USART1 started in C since the model last looked reach the board in one
    # call (on_tx_run), and a world's steps, which send nothing, run in order at the
    # bus's next run rather than stopping the CPU within the reply horizon: the same
    # session (a gait uploaded, played and stopped) must give the same bytes on the bus
    # at the same times, the same PC bytes, counts, servo positions, world samples,
    # instruction count, sleeps and exception entries as one call a byte, and as
    # following the world's steps
    sends = _pc_session(tmp_path)
    sizes, board = _on_a_board(image, sends)
    assert board[2].sent > 500 and board[2].received > 300 and board[2].blocked == 0
    assert sum(sizes) > 500 and max(sizes) > 4  # packets' bytes, many to a call
    assert len(board[4][0]) > 50  # the world sampled throughout
    assert board == _on_a_board(image, sends, in_runs=False)[1]
    assert board == _on_a_board(image, sends, world_steps_wait=False)[1]


def test_in_real_time_the_thread_runs_whole_steps_not_a_spin(image):
    # between the PC's bytes the thread waits until a step's time is due: running at once
    # for the time its last run took, it spins in steps as short as itself and takes a
    # whole core however fast the board runs (tens of thousands of steps a second); while
    # the link is quiet the steps are longer (each wake-up costs the host more than the
    # emulated millisecond), and once the PC sends they are short again
    with McuFirmware(image) as fw:
        time.sleep(QUIET_AFTER_S + 0.1)
        steps: list[tuple[float, float]] = []  # (emulated time, length of the run)
        board = fw.board
        run_until = board.run_until
        with fw.lock:

            def counted(t: float) -> None:
                steps.append((t, t - board.now()))
                run_until(t)

            board.run_until = counted  # type: ignore[method-assign]
        time.sleep(0.5)
        quiet = len(steps)
        with serial.Serial(fw.pc_link, PC_LINK_BAUD, timeout=5.0) as link:
            link.write(PING)
            time.sleep(QUIET_AFTER_S / 2)  # short steps for QUIET_AFTER_S after the last byte
            with fw.lock:
                board.run_until = run_until  # type: ignore[method-assign]
            answer = link.read(len(PONG))
    assert fw.error is None and answer == PONG
    assert 0 < quiet <= 1.5 * 0.5 / QUIET_STEP_S
    assert sorted(length for _, length in steps[:quiet])[quiet // 2] > 2 * STEP_S
    busy = sorted(length for _, length in steps[quiet:])  # a catch-up or two to the PING
    assert len(busy) >= 10 and busy[len(busy) * 9 // 10] <= STEP_S + 1e-9


@pytest.mark.slow
@pytest.mark.serial  # the store runs in real time on a pty
@pytest.mark.timeout(240)
def test_the_watchdog_is_never_starved_by_a_32k_library_store(image, tmp_path):
    frames = 32 * 1024 // (2 * len(SNAKE5_IDS)) - 16  # a table of just under 32 KB
    path = save(wave_table(frames=frames), tmp_path)
    bus = replace(SimOptions.from_query(""), robot="snake5").build_bus()
    with McuFirmware(image, bus=bus) as fw:
        fw.board.mcu.iwdg.lsi_hz = LSI_FASTEST_HZ  # the shortest timeout the chip can have
        time.sleep(0.3)
        result = cli("library", "store", "0", str(path), "--port", fw.pc_link, env=SLOW_HOST)
        assert result.exit_code == 0, result.output
        with fw.lock:
            m = fw.board.mcu
            gap, timeout = m.iwdg.largest_gap, m.iwdg.timeout_s()
            erases, resets = m.flash.erases, list(m.resets)
    assert fw.error is None
    assert resets == []
    assert erases >= 16  # the 32 KB slot's pages really were erased and written
    assert timeout < WATCHDOG_MS / 1000  # the fast LSI's timeout, shorter than nominal
    print(f"largest gap between watchdog feeds: {gap * 1000:.1f} ms of {timeout * 1000:.0f} ms")
    assert gap < 0.5 * timeout


@pytest.mark.slow
@pytest.mark.serial  # the gait is uploaded in real time on a pty
def test_the_cpu_sleeps_between_the_bytes_of_a_packet(image, tmp_path):
    # the bus's transmitter is interrupt driven (TXE feeds a byte, TC turns the line back),
    # so the main loop waits for an interrupt while a packet goes out, as it does between
    # packets: beyond SysTick's wake-ups it falls asleep again at least once for every
    # byte sent. A loop that polls until TC sleeps only between packets, far fewer times
    with EmulatedRobot("snake5", board="cm530") as robot:
        port = robot.info.pc_link
        cli_json("upload", save(wave_table(), tmp_path), "--port", port, env=SLOW_HOST)
        assert cli_json("play", "--port", port, env=SLOW_HOST)["state"] == "PLAYING"
        fw = robot._mcu  # noqa: SLF001 - the test drives the playing board itself
        assert fw is not None
        fw.stop()
        board = fw.board
        m = board.mcu
        sent, sleeps, ticks = board.bus_stats.sent, m.cpu.sleeps, m.systick.fired
        board.run_for(0.2)
        sent, sleeps = board.bus_stats.sent - sent, m.cpu.sleeps - sleeps
        ticks = m.systick.fired - ticks
    assert sent > 300  # the gait's packets went out throughout
    assert sleeps - ticks >= sent
