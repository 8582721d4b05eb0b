"""Telemetry samples as an MCAP file (for Foxglove and PlotJuggler): one JSON message per
sample on ``/snakebot/telemetry`` (what ``--json`` prints, which ``snakebot compare``
reads), and the JSON live topics of :mod:`snakebot.formats.live_topics`
(``/joint_states``, ``/snakebot/servos``, ``/snakebot/controller``, ``/tf``, ...) with the
schemas a live Foxglove server advertises, each described by its JSON Schema, stamped with
the wall clock. The bodies' ``/scene`` is not among them: a controller's telemetry has no
physics world to draw. Needs the optional ``mcap`` package
(``pip install 'snakebot[record]'``)."""

from __future__ import annotations

import json
import time
from types import TracebackType
from typing import IO, Any

from snakebot.errors import InputError
from snakebot.formats.live_topics import JSON_CHANNELS

TOPIC = "/snakebot/telemetry"
SCHEMA_NAME = "snakebot.Telemetry"
SCHEMA = {
    "type": "object",
    "title": SCHEMA_NAME,
    "properties": {
        "t": {"type": "number", "description": "seconds since monitoring began"},
        "controller": {"type": "object"},
        "servos": {"type": "array", "items": {"type": "object"}},
    },
}
"""What each message holds: :meth:`snakebot.link.controller.monitor.Sample.as_record`."""


FLUSH_S = 1.0
"""How often the chunk in progress is written to the file: what a SIGKILL can lose."""


class McapUnavailable(InputError):
    """The mcap package is not installed."""


class McapLog:
    """Writes telemetry records to an open binary stream, one chunk a second;
    :meth:`close` writes the index (a file cut short without it still holds every
    finished chunk, and ``snakebot compare`` reads it)."""

    def __init__(self, stream: IO[bytes]) -> None:
        try:
            from mcap.writer import Writer
        except ImportError:
            raise McapUnavailable(
                "recording MCAP needs the mcap package: pip install 'snakebot[record]' (or pip "
                "install mcap), or record as CSV"
            ).about("mcap_path", "csv_path") from None
        self._writer = Writer(stream)
        self._writer.start(profile="", library="snakebot")
        self._channels = {
            topic: self._writer.register_channel(
                topic=topic,
                message_encoding="json",
                schema_id=self._writer.register_schema(
                    name=name, encoding="jsonschema", data=json.dumps(schema).encode()
                ),
            )
            for topic, (name, schema) in {TOPIC: (SCHEMA_NAME, SCHEMA), **JSON_CHANNELS}.items()
        }
        self._writer.flush()  # the header, schema and channel: a cut file still reads
        self._flushed = time.monotonic()

    def write(self, record: dict[str, Any], stamp_ns: int | None = None) -> None:
        """One sample's telemetry record, at ``stamp_ns`` (default: now)."""
        self.log(TOPIC, record, stamp_ns)

    def log(self, topic: str, message: dict[str, Any], stamp_ns: int | None = None) -> None:
        """One message on ``topic`` (the telemetry's or a JSON live topic), at ``stamp_ns``
        (default: now). The chunk in progress is written out once it is :data:`FLUSH_S`
        old, so a file cut by a kill holds every message but those of the last second."""
        stamp = time.time_ns() if stamp_ns is None else stamp_ns
        self._writer.add_message(
            channel_id=self._channels[topic],
            log_time=stamp,
            publish_time=stamp,
            data=json.dumps(message).encode(),
        )
        now = time.monotonic()
        if now - self._flushed >= FLUSH_S:
            self._writer.flush()
            self._flushed = now

    def close(self) -> None:
        self._writer.finish()

    def __enter__(self) -> McapLog:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()
