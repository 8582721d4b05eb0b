"""A real Foxglove WebSocket client for the tests: it speaks the Foxglove protocol
(subprotocol foxglove.websocket.v1) with the ``websockets`` package, reads the channels a
server advertises, subscribes to some and decodes their JSON messages."""

from __future__ import annotations

import json
import struct
import threading
import time
from dataclasses import dataclass, field

SUBPROTOCOLS = ["foxglove.websocket.v1", "foxglove.sdk.v1"]
"""The Foxglove WebSocket protocol's subprotocol, by its first name and by the one the
foxglove-sdk server speaks since it was renamed (the messages are the same)."""
MESSAGE_DATA = 0x01


def advertised(ws, topics: set[str], timeout: float = 10) -> dict[str, dict]:
    """The channels the server advertises, by topic, once every one of ``topics`` is."""
    channels: dict[str, dict] = {}
    deadline = time.monotonic() + timeout
    while not topics <= set(channels) and time.monotonic() < deadline:
        message = json.loads(ws.recv(timeout=timeout))
        if message["op"] == "advertise":
            channels.update({c["topic"]: c for c in message["channels"]})
    return channels


def subscribe(ws, channels: dict[str, dict], topics: list[str]) -> dict[int, str]:
    """Subscribe to ``topics``; the subscription IDs by which messages come, to topics."""
    wanted = {sid: topic for sid, topic in enumerate(topics, start=1)}
    subscriptions = [{"id": sid, "channelId": channels[t]["id"]} for sid, t in wanted.items()]
    ws.send(json.dumps({"op": "subscribe", "subscriptions": subscriptions}))
    return wanted


def decode(data: bytes | str, wanted: dict[int, str]) -> tuple[str, dict] | None:
    """A binary messageData frame as (topic, message); None for anything else."""
    if isinstance(data, bytes) and data[0] == MESSAGE_DATA:
        sid, _ = struct.unpack_from("<IQ", data, 1)
        return wanted[sid], json.loads(data[13:])
    return None


@dataclass
class Listener:
    """A client in a thread: it connects to ws://127.0.0.1:``port`` as soon as a server
    listens there (within ``timeout``), subscribes to ``topics`` and keeps every message
    until :meth:`stop`, or until the server goes away. Run the command under test in the
    main thread meanwhile (its signal handling needs the main thread)."""

    port: int
    topics: list[str]
    timeout: float = 20.0
    channels: dict[str, dict] = field(default_factory=dict)
    messages: dict[str, list[dict]] = field(default_factory=dict)
    error: BaseException | None = None

    def __post_init__(self) -> None:
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def _run(self) -> None:
        from websockets.exceptions import ConnectionClosed
        from websockets.sync.client import connect

        deadline = time.monotonic() + self.timeout
        try:
            while True:
                try:
                    ws = connect(
                        f"ws://127.0.0.1:{self.port}", subprotocols=SUBPROTOCOLS, open_timeout=5
                    )
                    break
                except OSError:
                    if time.monotonic() > deadline or self._stop.is_set():
                        raise
                    time.sleep(0.05)
            with ws:
                assert ws.subprotocol in SUBPROTOCOLS
                assert json.loads(ws.recv(timeout=10))["op"] == "serverInfo"
                self.channels = advertised(ws, set(self.topics))
                wanted = subscribe(ws, self.channels, self.topics)
                while True:
                    try:
                        got = decode(ws.recv(timeout=0.2), wanted)
                    except TimeoutError:
                        if self._stop.is_set():
                            return  # asked to stop, and nothing more has come for 0.2 s
                        continue
                    except ConnectionClosed:
                        return
                    if got is not None:
                        self.messages.setdefault(got[0], []).append(got[1])
        except BaseException as exc:  # handed to the test by stop()
            self.error = exc

    def stop(self) -> Listener:
        self._stop.set()
        self._thread.join(timeout=10)
        if self.error is not None:
            raise self.error
        return self


def free_port() -> int:
    """A TCP port free on the loopback now (for a server the test starts next)."""
    import socket

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])
