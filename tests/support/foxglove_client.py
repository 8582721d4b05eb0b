"""A real Foxglove WebSocket client for the tests: it speaks the Foxglove protocol
(subprotocol foxglove.websocket.v1) with the ``websockets`` package, reads the channels a
server advertises, subscribes to some and decodes their messages as a Foxglove client
does, from what the server advertises: JSON as JSON, protobuf (Foxglove's own messages)
with the ``protobuf`` package, its message class built from the FileDescriptorSet the
channel carries."""

from __future__ import annotations

import base64
import json
import struct
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

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


def protobuf_class(name: str, descriptors: bytes) -> type:
    """The class of protobuf message ``name`` described by ``descriptors`` (a serialized
    FileDescriptorSet: the message's file and those it imports)."""
    from google.protobuf import descriptor_pb2, descriptor_pool, message_factory

    pool = descriptor_pool.DescriptorPool()
    for file in descriptor_pb2.FileDescriptorSet.FromString(descriptors).file:
        pool.Add(file)  # each comes after the files it imports
    return message_factory.GetMessageClass(pool.FindMessageTypeByName(name))


def decoder(channel: dict) -> Callable[[bytes], Any]:
    """How the messages of ``channel`` read, by its encoding: JSON as a dict, protobuf as
    a message of the class its schema describes (advertised base64-encoded)."""
    if channel["encoding"] == "json":
        return json.loads
    assert (channel["encoding"], channel["schemaEncoding"]) == ("protobuf", "protobuf"), channel
    schema = base64.b64decode(channel["schema"])
    return protobuf_class(channel["schemaName"], schema).FromString


Subscriptions = dict[int, tuple[str, Callable[[bytes], Any]]]
"""Subscription ID -> (topic, its decoder)."""


def subscribe(ws, channels: dict[str, dict], topics: list[str]) -> Subscriptions:
    """Subscribe to ``topics``; the subscription IDs by which messages come, to topics
    and how their messages read."""
    wanted = {sid: (t, decoder(channels[t])) for sid, t in enumerate(topics, start=1)}
    subscriptions = [{"id": sid, "channelId": channels[t]["id"]} for sid, (t, _) in wanted.items()]
    ws.send(json.dumps({"op": "subscribe", "subscriptions": subscriptions}))
    return wanted


def decode(data: bytes | str, wanted: Subscriptions) -> tuple[str, Any] | None:
    """A binary messageData frame as (topic, message); None for anything else."""
    if isinstance(data, bytes) and data[0] == MESSAGE_DATA:
        sid, _ = struct.unpack_from("<IQ", data, 1)
        topic, read = wanted[sid]
        return topic, read(data[13:])
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
    messages: dict[str, list[Any]] = field(default_factory=dict)
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


def in_frame(transforms: dict[str, dict], frame: str, point: Any, root: str = "odom") -> Any:
    """``point`` (x, y, z in ``frame``) in ``root``, through ``transforms`` (``/tf``'s
    transforms by child frame), as the 3-D panel places a shape locked to ``frame``."""
    import numpy as np

    point = np.asarray(point, dtype=float)
    while frame != root:
        t = transforms[frame]
        (x, y, z), w = (t["rotation"][k] for k in "xyz"), t["rotation"]["w"]
        u = np.array([x, y, z])
        point = point + 2 * np.cross(u, np.cross(u, point) + w * point)  # rotated by t
        point = point + np.array([t["translation"][k] for k in "xyz"])
        frame = t["parent_frame_id"]
    return point
