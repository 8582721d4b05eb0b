"""What a picture or a video shows of a run: sample times, body poses and joint angles."""

from __future__ import annotations

from typing import NamedTuple, Protocol

import numpy as np


class Motion(Protocol):
    """A run as a video shows it (a world's record has it): sample times (s), body poses
    (x, y in robot units, theta in radians) and joint angles (radians)."""

    t: np.ndarray
    pose: np.ndarray
    phi: np.ndarray


class StateMotion(NamedTuple):
    """A motion given as arrays, e.g. a prediction's states ``q`` split up."""

    t: np.ndarray
    pose: np.ndarray
    phi: np.ndarray

    @classmethod
    def of_states(cls, t: np.ndarray, q: np.ndarray) -> StateMotion:
        return cls(t, q[:, :3], q[:, 3:])


def sample_index(t: np.ndarray, now: float) -> int:
    """The index of the last sample of ``t`` at or before ``now`` (the first if none is)."""
    k = int(np.searchsorted(t, now, side="right")) - 1
    return max(0, min(k, len(t) - 1))
