"""Every transport timeout and retry count has a name, a default, and an environment
variable that overrides it; a keyword argument overrides both (as esptool does).

=============================  =====================  ==========================
setting                        environment variable   default
=============================  =====================  ==========================
retries after the first try    SNAKEBOT_RETRIES       ``DEFAULT_RETRIES``
USB adapter latency            SNAKEBOT_LATENCY_MS    ``timing.USB_LATENCY_S``
host scheduling margin         SNAKEBOT_MARGIN_MS     ``timing.HOST_MARGIN_S`` (a
                                                      controller on a pty:
                                                      ``timing.PROGRAM_MARGIN_S``)
servo Return Delay Time        SNAKEBOT_RETURN_DELAY_US ``timing.DEFAULT_RETURN_DELAY_US``
instruction echo on the bus    SNAKEBOT_ECHO          ``auto`` (also on / off)
shortest echo-probe wait       SNAKEBOT_ECHO_PROBE_MS ``timing.ECHO_PROBE_MIN_S``
=============================  =====================  ==========================
"""

from __future__ import annotations

import os
from typing import Literal

from snakebot.link.transport import timing
from snakebot.link.transport.errors import TransportSettingError

DEFAULT_RETRIES = 2
"""Extra attempts after a timed-out or corrupt reply (so three tries in all)."""

MAX_RETRIES = 100

ENV_RETRIES = "SNAKEBOT_RETRIES"
ENV_LATENCY_MS = "SNAKEBOT_LATENCY_MS"
ENV_MARGIN_MS = "SNAKEBOT_MARGIN_MS"
ENV_RETURN_DELAY_US = "SNAKEBOT_RETURN_DELAY_US"
ENV_ECHO = "SNAKEBOT_ECHO"
ENV_ECHO_PROBE_MS = "SNAKEBOT_ECHO_PROBE_MS"

EchoSetting = bool | Literal["auto"]

_ECHO_WORDS: dict[str, EchoSetting] = {
    "auto": "auto",
    "on": True,
    "1": True,
    "true": True,
    "yes": True,
    "off": False,
    "0": False,
    "false": False,
    "no": False,
}


def _env_float(name: str, low: float, high: float) -> float | None:
    text = os.environ.get(name, "").strip()
    if not text:
        return None
    try:
        value = float(text)
    except ValueError:
        value = float("nan")
    if not low <= value <= high:  # also rejects nan
        raise TransportSettingError(
            f"{name}={text!r} is not a number from {low:g} to {high:g}; "
            f"set it to e.g. {low + 1:g} or unset it"
        )
    return value


def resolve_retries(value: int | None = None) -> int:
    """Retries: the keyword if given, else ``SNAKEBOT_RETRIES``, else ``DEFAULT_RETRIES``."""
    if value is None:
        env = _env_float(ENV_RETRIES, 0, MAX_RETRIES)
        if env is None:
            return DEFAULT_RETRIES
        if env != int(env):
            raise TransportSettingError(
                f"{ENV_RETRIES}={os.environ[ENV_RETRIES]!r} is not a whole number; "
                "set it to e.g. 2 or unset it"
            )
        return int(env)
    if not isinstance(value, int) or not 0 <= value <= MAX_RETRIES:
        raise TransportSettingError(
            f"retries must be a whole number from 0 to {MAX_RETRIES}, got {value!r}"
        )
    return value


def _resolve_seconds(
    value: float | None, env_name: str, scale: float, default: float, what: str
) -> float:
    if value is None:
        env = _env_float(env_name, 0, 10_000)
        return default if env is None else env * scale
    if not value >= 0:
        raise TransportSettingError(f"{what} must not be negative, got {value!r}")
    return float(value)


def resolve_latency_s(value: float | None = None) -> float:
    """USB latency margin in seconds: keyword, else ``SNAKEBOT_LATENCY_MS``, else default."""
    return _resolve_seconds(value, ENV_LATENCY_MS, 1e-3, timing.USB_LATENCY_S, "latency_s")


def resolve_margin_s(value: float | None = None, default: float = timing.HOST_MARGIN_S) -> float:
    """Host scheduling margin in seconds: keyword, else ``SNAKEBOT_MARGIN_MS``, else
    ``default``."""
    return _resolve_seconds(value, ENV_MARGIN_MS, 1e-3, default, "margin_s")


def resolve_return_delay_us(value: float | None = None) -> float:
    """Servo Return Delay Time in microseconds: keyword, else ``SNAKEBOT_RETURN_DELAY_US``,
    else the AX-12 factory value."""
    return _resolve_seconds(
        value, ENV_RETURN_DELAY_US, 1.0, timing.DEFAULT_RETURN_DELAY_US, "return_delay_us"
    )


def resolve_echo_probe_s(value: float | None = None) -> float:
    """Shortest wait for the echo of the "auto" mode's probe, in seconds: keyword, else
    ``SNAKEBOT_ECHO_PROBE_MS``, else default."""
    return _resolve_seconds(value, ENV_ECHO_PROBE_MS, 1e-3, timing.ECHO_PROBE_MIN_S, "echo_probe_s")


def resolve_echo(value: EchoSetting | None = None) -> EchoSetting:
    """Echo handling: True, False or "auto"; keyword, else ``SNAKEBOT_ECHO``, else "auto"."""
    if value is None:
        text = os.environ.get(ENV_ECHO, "").strip().lower()
        if not text:
            return "auto"
        if text not in _ECHO_WORDS:
            raise TransportSettingError(
                f"{ENV_ECHO}={os.environ[ENV_ECHO]!r} is not understood; "
                "set it to auto, on or off, or unset it"
            )
        return _ECHO_WORDS[text]
    if value is True or value is False or value == "auto":
        return value
    raise TransportSettingError(f"echo must be True, False or 'auto', got {value!r}")
