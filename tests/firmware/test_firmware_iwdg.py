"""The independent-watchdog driver (firmware/hal/hal_iwdg.c) against a model of the IWDG
registers: the key sequence comes in the documented order, and the prescaler and reload
it picks give the requested timeout (at the nominal 40 kHz LSI) to within one count."""

from __future__ import annotations

import pytest
from firmware_support import RegisterModels, hal_fixture

IWDG = 0x40003000
KR, PR, RLR, SR = IWDG, IWDG + 4, IWDG + 8, IWDG + 12
LSI_HZ = 40_000

CDEF = """
void hal_iwdg_start(uint32_t timeout_ms);
void hal_iwdg_feed(void);
"""


class IwdgModel:
    def __init__(self) -> None:
        self.log: list[tuple[str, int]] = []
        self.pr = 0
        self.rlr = 0xFFF
        self.access = False
        self.running = False

    def read32(self, addr):
        assert addr == SR, f"read of {addr:#x}"
        return 0  # updates done

    def write32(self, addr, value):
        if addr == KR:
            self.log.append(("KR", value))
            if value == 0xCCCC:
                self.running = True
            self.access = value == 0x5555
        elif addr in (PR, RLR):
            assert self.access, "PR/RLR written without the 0x5555 access key"
            self.log.append(("PR" if addr == PR else "RLR", value))
            if addr == PR:
                self.pr = value
            else:
                self.rlr = value
        else:
            raise AssertionError(f"write of {addr:#x}")

    def timeout_ms(self) -> float:
        return self.rlr * (4 << self.pr) / LSI_HZ * 1000


MODELS = RegisterModels()


hal = hal_fixture("_hal_iwdg_host", ["hal_iwdg.c"], ["hal_iwdg.h"], CDEF, MODELS)


@pytest.fixture
def model():
    with MODELS.use(IwdgModel()) as m:
        yield m


@pytest.mark.parametrize("timeout_ms", [1, 100, 409, 410, 500, 1000, 5000, 26000])
def test_timeout_is_met_to_within_one_count(hal, model, timeout_ms):
    hal.lib.hal_iwdg_start(timeout_ms)
    assert model.running
    assert 0 <= model.pr <= 6 and 1 <= model.rlr <= 0xFFF
    count_ms = (4 << model.pr) / LSI_HZ * 1000
    assert timeout_ms <= model.timeout_ms() < timeout_ms + count_ms
    # the finest prescaler that can hold it: one step finer would overflow the reload
    if model.pr > 0:
        assert timeout_ms * LSI_HZ / 1000 / (4 << (model.pr - 1)) > 0xFFF


def test_key_sequence_and_feed(hal, model):
    hal.lib.hal_iwdg_start(500)
    hal.lib.hal_iwdg_feed()
    assert model.log == [
        ("KR", 0xCCCC),  # start (also starts the LSI)
        ("KR", 0x5555),  # unlock PR and RLR
        ("PR", 1),  # /8
        ("RLR", 2500),  # 2500 * 8 / 40 kHz = 500 ms
        ("KR", 0xAAAA),  # reload with the new values
        ("KR", 0xAAAA),  # the feed
    ]


def test_longest_timeout_is_clamped(hal, model):
    hal.lib.hal_iwdg_start(10_000_000)
    assert (model.pr, model.rlr) == (6, 0xFFF)
