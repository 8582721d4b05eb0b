"""The button debouncer (firmware/core/buttons.c) and the library panel on it
(firmware/core/lib_panel.c: U/D pick a slot, START plays or stops, the LEDs show the
slot), run on the host through snakebot._core."""

from __future__ import annotations

from hypothesis import given
from hypothesis import strategies as st

from snakebot.core import ffi, lib

U, D, START = lib.CTL_BUTTONS_U, lib.CTL_BUTTONS_D, lib.CTL_BUTTONS_START
SCANS = lib.BUTTONS_DEBOUNCE_SCANS
ALL = U | D | lib.CTL_BUTTONS_L | lib.CTL_BUTTONS_R | START


def scanner():
    b = ffi.new("buttons_t *")
    lib.buttons_init(b)
    return b


def presses(samples: list[int]) -> list[int]:
    b = scanner()
    return [lib.buttons_scan(b, s) for s in samples]


class Reference:
    """What debouncing means, button by button: a button's state changes once its
    samples have differed from it SCANS times in a row."""

    def __init__(self) -> None:
        self.held = 0
        self.run = {bit: 0 for bit in range(5)}

    def scan(self, raw: int) -> int:
        pressed = 0
        for bit in self.run:
            mask = 1 << bit
            if (raw ^ self.held) & mask:
                self.run[bit] += 1
                if self.run[bit] == SCANS:
                    self.held ^= mask
                    self.run[bit] = 0
                    pressed |= mask & self.held
            else:
                self.run[bit] = 0
        return pressed


def test_a_clean_press_counts_once_after_the_debounce_time_and_again_after_release():
    held = [START] * 10 + [0] * 10 + [START] * 10
    out = presses(held)
    assert [i for i, p in enumerate(out) if p] == [SCANS - 1, 20 + SCANS - 1]
    assert all(p in (0, START) for p in out)


def test_bounce_shorter_than_the_debounce_time_is_ignored():
    bounce = [START, 0, START, START, 0, START, START, START, 0] * 5
    assert not any(presses(bounce))


def test_a_bouncing_button_does_not_hold_up_another():
    samples = [START | (U if i % 2 else 0) for i in range(SCANS)]
    assert presses(samples)[-1] == START


@given(st.lists(st.integers(0, ALL), max_size=120))
def test_the_scanner_agrees_with_the_per_button_definition(samples):
    ref = Reference()
    assert presses(samples) == [ref.scan(s) for s in samples]


@given(
    st.lists(st.tuples(st.sampled_from([U, D, START, U | START]), st.integers(1, 12)), max_size=20)
)
def test_every_press_held_long_enough_counts_exactly_once(runs):
    """Presses separated by releases: each press held at least SCANS scans and followed by
    a release as long counts once; shorter ones not at all."""
    samples: list[int] = []
    expected = {U: 0, D: 0, START: 0}
    for mask, length in runs:
        samples += [mask] * length + [0] * SCANS
        if length >= SCANS:
            for bit in expected:
                expected[bit] += bool(mask & bit)
    out = presses(samples)
    assert {bit: sum(bool(p & bit) for p in out) for bit in expected} == expected


# ---- the panel ----------------------------------------------------------------------------


class Panel:
    def __init__(self, slots: int) -> None:
        self.p = ffi.new("lib_panel_t *")
        lib.lib_panel_init(self.p)
        self.slots = slots
        self.playing = False

    def press(self, button: int) -> int:
        """Hold ``button`` long enough, then release it; the action it caused."""
        actions = [
            lib.lib_panel_tick(self.p, button, self.slots, self.playing) for _ in range(SCANS)
        ]
        actions += [lib.lib_panel_tick(self.p, 0, self.slots, self.playing) for _ in range(SCANS)]
        done = [a for a in actions if a != lib.LIB_PANEL_NOTHING]
        assert len(done) <= 1
        return done[0] if done else lib.LIB_PANEL_NOTHING

    @property
    def leds(self) -> int:
        return lib.lib_panel_leds(self.p, self.playing)


def test_up_and_down_pick_slots_wrapping_round_and_the_leds_show_the_slot():
    panel = Panel(8)
    assert panel.p.slot == 0 and panel.leds == 0
    seen = []
    for _ in range(9):
        assert panel.press(U) == lib.LIB_PANEL_NOTHING
        seen.append((panel.p.slot, panel.leds))
    assert seen == [(s % 8, s % 8) for s in range(1, 10)]
    panel.press(D)
    panel.press(D)
    assert panel.p.slot == 7 and panel.leds == 0b111


def test_start_plays_the_picked_slot_then_stops():
    panel = Panel(8)
    panel.press(U)
    panel.press(U)
    assert panel.press(START) == lib.LIB_PANEL_PLAY and panel.p.slot == 2
    panel.playing = True
    assert panel.leds == 2 | lib.CTL_LEDS_PLAY
    panel.press(U)  # picking another slot while playing does not stop it
    assert panel.p.slot == 3
    assert panel.press(START) == lib.LIB_PANEL_STOP


def test_a_library_of_one_slot_or_none():
    one = Panel(1)
    one.press(U)
    one.press(D)
    assert one.p.slot == 0 and one.press(START) == lib.LIB_PANEL_PLAY
    none = Panel(0)
    assert none.press(START) == lib.LIB_PANEL_NOTHING
