"""The transaction timeout formula, checked against values worked out by hand, and the
settings that feed it (keywords beat environment variables beat named defaults)."""

from __future__ import annotations

import pytest

from snakebot.link.transport import (
    DEFAULT_RETRIES,
    USB_LATENCY_S,
    BusTiming,
    DxlClient,
    TransportSettingError,
    reply_timeout_s,
    wire_time_s,
)
from snakebot.settings import SettingError


def test_wire_time_is_ten_bits_per_byte():
    assert wire_time_s(10, 1_000_000) == pytest.approx(100e-6)
    assert wire_time_s(1, 9600) == pytest.approx(1 / 960)


def test_read_of_two_bytes_at_1_mbps_with_factory_settings():
    # READ = 8 bytes out, status with 2 data bytes = 8 bytes back: 16 bytes = 160 us,
    # + 500 us return delay + 16 ms FTDI latency timer + 4 ms host margin = 20.66 ms.
    assert reply_timeout_s(
        8, 8, 1_000_000, return_delay_us=500, latency_s=0.016, margin_s=0.004
    ) == pytest.approx(0.02066)


def test_pc_link_at_57600_with_no_margins():
    # 16 bytes x 10 bits / 57600 baud = 2.7778 ms.
    assert reply_timeout_s(8, 8, 57600, return_delay_us=0, latency_s=0, margin_s=0) == (
        pytest.approx(160 / 57600)
    )


def test_bus_timing_counts_the_status_overhead():
    # 8-byte instruction + 6-byte status frame + 2 data bytes at 115200: 160 bits,
    # + 1 ms latency = 1.3889 ms + 1 ms.
    timing = BusTiming(baudrate=115200, return_delay_us=0, latency_s=0.001, margin_s=0)
    assert timing.reply_timeout_s(8, 2) == pytest.approx(160 / 115200 + 0.001)


def test_timeout_grows_with_slower_baud_and_longer_packets():
    def t(tx: int, rx: int, baud: int) -> float:
        return reply_timeout_s(tx, rx, baud, return_delay_us=0, latency_s=0, margin_s=0)

    assert t(8, 8, 57600) > t(8, 8, 115200) > t(8, 8, 1_000_000)
    assert t(8, 250, 1_000_000) - t(8, 8, 1_000_000) == pytest.approx(242 * 10e-6)


def test_bad_inputs_are_refused():
    with pytest.raises(ValueError):
        wire_time_s(8, 0)
    with pytest.raises(ValueError):
        reply_timeout_s(8, 8, 1_000_000, latency_s=-1)


# -- settings ---------------------------------------------------------------------------

ENV = (
    "SNAKEBOT_RETRIES",
    "SNAKEBOT_LATENCY_MS",
    "SNAKEBOT_MARGIN_MS",
    "SNAKEBOT_RETURN_DELAY_US",
    "SNAKEBOT_ECHO",
    "SNAKEBOT_ECHO_PROBE_MS",
)


@pytest.fixture
def clean_env(monkeypatch):
    for name in ENV:
        monkeypatch.delenv(name, raising=False)
    return monkeypatch


def test_defaults_without_environment(clean_env):
    with DxlClient("loop://") as bus:
        assert bus.retries == DEFAULT_RETRIES
        assert bus.timing.latency_s == USB_LATENCY_S
        assert bus.timing.return_delay_us == 500
        assert bus.timing.baudrate == 1_000_000
        assert bus.echo is None  # auto, not decided yet


def test_environment_overrides_defaults(clean_env):
    clean_env.setenv("SNAKEBOT_RETRIES", "5")
    clean_env.setenv("SNAKEBOT_LATENCY_MS", "1")
    clean_env.setenv("SNAKEBOT_MARGIN_MS", "0.5")
    clean_env.setenv("SNAKEBOT_RETURN_DELAY_US", "0")
    clean_env.setenv("SNAKEBOT_ECHO", "on")
    with DxlClient("loop://", 57600) as bus:
        assert bus.retries == 5
        assert bus.timing == BusTiming(57600, 0.0, 0.001, 0.0005)
        assert bus.echo is True


def test_keywords_override_environment(clean_env):
    clean_env.setenv("SNAKEBOT_RETRIES", "5")
    clean_env.setenv("SNAKEBOT_LATENCY_MS", "1")
    clean_env.setenv("SNAKEBOT_ECHO", "on")
    with DxlClient("loop://", retries=0, latency_s=0.002, echo=False) as bus:
        assert bus.retries == 0
        assert bus.timing.latency_s == 0.002
        assert bus.echo is False


@pytest.mark.parametrize(
    ("name", "value"),
    [
        ("SNAKEBOT_RETRIES", "many"),
        ("SNAKEBOT_RETRIES", "-1"),
        ("SNAKEBOT_RETRIES", "2.5"),
        ("SNAKEBOT_LATENCY_MS", "fast"),
        ("SNAKEBOT_LATENCY_MS", "nan"),
        ("SNAKEBOT_ECHO", "maybe"),
    ],
)
def test_bad_environment_values_name_the_variable(clean_env, name, value):
    clean_env.setenv(name, value)
    with pytest.raises(SettingError, match=name):
        DxlClient("loop://")


def test_bad_keywords_are_refused(clean_env):
    with pytest.raises(TransportSettingError):
        DxlClient("loop://", retries=-1)
    with pytest.raises(TransportSettingError):
        DxlClient("loop://", echo="sometimes")  # type: ignore[arg-type]
