"""The QEMU stage of `make test`, and on a busy machine the serial stage too, run in the
kernel's round-robin real-time class where that is allowed (the Makefile's FIRST), so
that busy processes beside them cannot delay an emulated reply. A third-party client
that polls a port without sleeping (dynamixel-sdk reads with a zero timeout in a loop
until its deadline) must not poll at that priority: it keeps its core from everything
below it, the kernel's tty work that carries the bytes between the ends of a pty
included, and its own replies then come late (measured beside two busy processes:
dynamixel-sdk timed out in 3 of 9 tests at real-time priority, none at the default one).
:func:`ordinary_priority` runs the calling thread, and what it starts, in the default
class meanwhile."""

from __future__ import annotations

import os
from collections.abc import Iterator
from contextlib import contextmanager


@contextmanager
def ordinary_priority() -> Iterator[None]:
    """The calling thread in the default scheduling class inside the block, back in its
    own class (real-time or not) after it."""
    policy = os.sched_getscheduler(0)
    param = os.sched_getparam(0)
    if policy == os.SCHED_OTHER:
        yield
        return
    os.sched_setscheduler(0, os.SCHED_OTHER, os.sched_param(0))
    try:
        yield
    finally:
        os.sched_setscheduler(0, policy, param)
