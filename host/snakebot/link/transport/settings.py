"""Every transport timeout and retry count has a name, a default, and an environment
variable that overrides it; a keyword argument overrides both (as esptool does).

=============================  =====================  ==========================
setting                        environment variable   default
=============================  =====================  ==========================
retries after the first try    SNAKEBOT_RETRIES       ``DEFAULT_RETRIES``
USB adapter latency            SNAKEBOT_LATENCY_MS    the adapter's own (``adapter``),
                                                      else ``timing.USB_LATENCY_S``
host scheduling margin         SNAKEBOT_MARGIN_MS     ``timing.HOST_MARGIN_S`` (a
                                                      controller on a pty:
                                                      ``timing.PROGRAM_MARGIN_S``)
servo Return Delay Time        SNAKEBOT_RETURN_DELAY_US ``timing.DEFAULT_RETURN_DELAY_US``
instruction echo on the bus    SNAKEBOT_ECHO          ``auto`` (also on / off)
shortest echo-probe wait       SNAKEBOT_ECHO_PROBE_MS ``timing.ECHO_PROBE_MIN_S``
=============================  =====================  ==========================

The variables, their ranges and defaults are rows of the one table in
:mod:`snakebot.settings`, which reads and checks them; this module adds the keyword
arguments and the transport's unit of time, the second.
"""

from __future__ import annotations

from typing import Literal

from snakebot import settings as table
from snakebot.errors import quoted
from snakebot.link.transport import timing
from snakebot.link.transport.errors import TransportSettingError

ENV_RETRIES = "SNAKEBOT_RETRIES"
ENV_LATENCY_MS = "SNAKEBOT_LATENCY_MS"
ENV_MARGIN_MS = "SNAKEBOT_MARGIN_MS"
ENV_RETURN_DELAY_US = "SNAKEBOT_RETURN_DELAY_US"
ENV_ECHO = "SNAKEBOT_ECHO"
ENV_ECHO_PROBE_MS = "SNAKEBOT_ECHO_PROBE_MS"

DEFAULT_RETRIES = table.default_int(ENV_RETRIES)
"""Extra attempts after a timed-out or corrupt reply (so three tries in all)."""

MAX_RETRIES = int(table.setting(ENV_RETRIES).high or 0)

EchoSetting = bool | Literal["auto"]


def resolve_retries(value: int | None = None) -> int:
    """Retries: the keyword if given, else ``SNAKEBOT_RETRIES``, else ``DEFAULT_RETRIES``."""
    if value is None:
        return table.resolve_int(ENV_RETRIES)
    if not isinstance(value, int) or not 0 <= value <= MAX_RETRIES:
        raise TransportSettingError(
            f"retries must be a whole number from 0 to {MAX_RETRIES}, got {quoted(value)}"
        )
    return value


def _resolve_seconds(
    value: float | None, env_name: str, per_unit: float, default: float, what: str
) -> float:
    if value is None:
        env = table.lookup(env_name)
        return default if env is None else float(env) / per_unit
    if not value >= 0:
        raise TransportSettingError(f"{what} must not be negative, got {quoted(value)}")
    return float(value)


def resolve_latency_s(value: float | None = None, adapter: float | None = None) -> float:
    """USB latency margin in seconds: keyword, else ``SNAKEBOT_LATENCY_MS``, else what the
    adapter reports (``adapter``, from :func:`snakebot.link.transport.adapter.latency_s`),
    else the default."""
    default = timing.USB_LATENCY_S if adapter is None else adapter
    return _resolve_seconds(value, ENV_LATENCY_MS, 1e3, default, "latency_s")


def resolve_margin_s(value: float | None = None, default: float = timing.HOST_MARGIN_S) -> float:
    """Host scheduling margin in seconds: keyword, else ``SNAKEBOT_MARGIN_MS``, else
    ``default``."""
    return _resolve_seconds(value, ENV_MARGIN_MS, 1e3, default, "margin_s")


def resolve_return_delay_us(value: float | None = None) -> float:
    """Servo Return Delay Time in microseconds: keyword, else ``SNAKEBOT_RETURN_DELAY_US``,
    else the AX-12 factory value."""
    return _resolve_seconds(
        value, ENV_RETURN_DELAY_US, 1.0, timing.DEFAULT_RETURN_DELAY_US, "return_delay_us"
    )


def resolve_echo_probe_s(value: float | None = None) -> float:
    """Shortest wait for the echo of the "auto" mode's probe, in seconds: keyword, else
    ``SNAKEBOT_ECHO_PROBE_MS``, else default."""
    return _resolve_seconds(value, ENV_ECHO_PROBE_MS, 1e3, timing.ECHO_PROBE_MIN_S, "echo_probe_s")


def resolve_echo(value: EchoSetting | None = None) -> EchoSetting:
    """Echo handling: True, False or "auto"; keyword, else ``SNAKEBOT_ECHO``, else "auto"."""
    if value is None:
        env = table.resolve(ENV_ECHO)
        return "auto" if env == "auto" else bool(env)
    if value is True or value is False or value == "auto":
        return value
    raise TransportSettingError(f"echo must be True, False or 'auto', got {quoted(value)}")
