"""Benchmark: the CPU the Foxglove server adds to `snakebot sim serve` at 50 Hz.

Each world's server (`snakebot sim serve --world kinematic|mujoco`, the firmware in QEMU)
runs for ``--seconds`` without --foxglove, then with `--foxglove 0` and a Foxglove client
(the `websockets` package, subprotocol foxglove.websocket.v1) subscribed to every topic
it advertises, in turn, ``--rounds`` times. The CPU is the server's Python process
(``utime + stime`` in ``/proc/<pid>/stat``), where the Foxglove server and all it sends
are, over the measured window after a warm-up; the figure is the difference, in percent
of one core (the firmware's QEMU, a process of its own that the server does not touch, is
shown beside: on a busy machine it varies by more than the whole figure). The goal:
under :data:`GOAL_PERCENT`. The robot stands still: the world and the server work as much
either way. A busy machine makes the figures noisy: run it on a quiet one.

    .venv/bin/python bench/bench_foxglove_cpu.py [--seconds 20] [--rounds 2]
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import threading
import time

from bench_serve_memory import firmware

GOAL_PERCENT = 5.0
WORLDS = ("kinematic", "mujoco")
WARM_UP_S = 5.0
SUBPROTOCOLS = ["foxglove.websocket.v1", "foxglove.sdk.v1"]
MESSAGE_DATA = 0x01


def cpu_s(pid: int) -> float:
    """CPU seconds (user + system) process ``pid`` has used."""
    with open(f"/proc/{pid}/stat") as f:
        fields = f.read().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


class Client(threading.Thread):
    """A Foxglove client subscribed to every channel; counts the messages it gets."""

    def __init__(self, url: str) -> None:
        super().__init__(daemon=True)
        self.url, self.messages, self.done = url, 0, threading.Event()

    def run(self) -> None:
        from websockets.exceptions import ConnectionClosed
        from websockets.sync.client import connect

        with connect(self.url, subprotocols=SUBPROTOCOLS, open_timeout=10) as ws:
            subscribed = False
            while not self.done.is_set():
                try:
                    data = ws.recv(timeout=0.5)
                except TimeoutError:
                    continue
                except ConnectionClosed:
                    return
                if isinstance(data, bytes):
                    self.messages += data[0] == MESSAGE_DATA
                    continue
                message = json.loads(data)
                if message["op"] == "advertise" and not subscribed:
                    subscriptions = [
                        {"id": k, "channelId": c["id"]} for k, c in enumerate(message["channels"])
                    ]
                    ws.send(json.dumps({"op": "subscribe", "subscriptions": subscriptions}))
                    subscribed = True


def measure(world: str, image: str, foxglove: bool, seconds: float) -> tuple[float, float, float]:
    """Percent of a core `sim serve`'s Python process and its QEMU take, and the messages
    a second the client got."""
    command = [sys.executable, "-m", "snakebot", "sim", "serve", "--world", world]
    command += ["--board", "qemu", "--firmware", image, "--report", "0", "--json"]
    command += ["--foxglove", "0"] if foxglove else []
    server = subprocess.Popen(command, stdout=subprocess.PIPE, text=True)
    try:
        assert server.stdout is not None
        first = json.loads(server.stdout.readline())
        pids = [server.pid, first["qemu_pid"]]
        client = Client(first["foxglove"]) if foxglove else None
        if client is not None:
            client.start()
        time.sleep(WARM_UP_S)
        got = client.messages if client else 0
        before, t0 = [cpu_s(p) for p in pids], time.monotonic()
        time.sleep(seconds)
        used = [cpu_s(p) - b for p, b in zip(pids, before, strict=True)]
        elapsed = time.monotonic() - t0
        rate = ((client.messages - got) / elapsed) if client else 0.0
        if client is not None:
            client.done.set()
        return 100 * used[0] / elapsed, 100 * used[1] / elapsed, rate
    finally:
        server.terminate()
        server.wait(30)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=20.0)
    parser.add_argument("--rounds", type=int, default=3)
    args = parser.parse_args()
    image = firmware("qemu")
    worst = 0.0
    for world in WORLDS:
        added = []
        for _ in range(args.rounds):
            without, qemu_without, _ = measure(world, image, False, args.seconds)
            with_, qemu_with, rate = measure(world, image, True, args.seconds)
            added.append(with_ - without)
            print(
                f"{world}: sim serve {without:.1f} % of a core without, {with_:.1f} % with "
                f"Foxglove ({rate:.0f} messages/s to the client); its QEMU {qemu_without:.1f} "
                f"% and {qemu_with:.1f} %"
            )
        worst = max(worst, statistics.median(added))
        print(f"{world}: Foxglove adds {statistics.median(added):.1f} % of a core (median)")
    print(f"goal: under {GOAL_PERCENT:g} % of a core: {'met' if worst < GOAL_PERCENT else 'MISS'}")
    return 0 if worst < GOAL_PERCENT else 1


if __name__ == "__main__":
    sys.exit(main())
