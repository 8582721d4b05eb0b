"""The in-process emulated controller (snakebot.sim.controller_pty) says how far the host
held it up: the longest time between two of its control ticks, which tests that record a
run use to tell a host that disturbed the recording from a wrong result."""

from __future__ import annotations

import time

from snakebot.sim.controller_pty import ControllerPty


def test_a_held_up_serving_thread_shows_in_the_longest_tick_gap():
    with ControllerPty(robot=None) as server:
        time.sleep(0.3)
        prompt = server.longest_tick_gap_s
        with server.lock:  # the serving loop waits for this lock: no tick meanwhile
            time.sleep(0.25)
        time.sleep(0.1)
        held = server.longest_tick_gap_s
    assert server.tick_ms / 1000 * 0.9 <= prompt < 0.25, prompt
    assert held >= 0.25, held
