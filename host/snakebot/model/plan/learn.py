"""What the floor does to a loop, learned as the closed loop runs.

The loops are fitted with the minimum-slip model; a world whose wheels slip (MuJoCo's,
or a real floor) moves the body by something else, but for the loops of one run
nearly by a fixed linear map of what the model said: a little shorter, a little
turned, some of the turn leaking into the translation. ``Response`` keeps that map, a
3x3 gain G with observed ~= G planned (position in body lengths, so that it weighs like
the heading), fitted by least squares over the loops played so far, the recent ones
weighing more (the loops shrink and change shape on the way), drawn towards the
identity while there are few of them. The next loop is fitted to move the model's body
by G^-1 of what the world should move it by.

Measured on MuJoCo (seeded targets, 3-link snake): this full map met twice the
tolerance at 11 of 12 targets; a map with three parameters (one complex gain for the
translation, one for the turn) at 8, as it cannot undo the turn that the snake's
loops add to its translation.
"""

from __future__ import annotations

import numpy as np

#: Each older loop's weight in the fit is this times the next one's.
FORGET = 0.7
#: Pull towards the identity, in squared motion (body lengths, radians) of one loop:
#: a loop of a tenth of a body length weighs 0.01, a third of the pull, so the first
#: loop alone moves the gain most of the way.
PRIOR = 0.003
#: A correction never asks the model for more than this times the wanted motion: a
#: gain fitted to few loops may be near singular, and its inverse must not send the
#: robot far off.
MOST_CORRECTION = 2.0


class Response:
    """The map from a loop's motion as planned to its motion as observed."""

    def __init__(self, scale: float) -> None:
        self.weights = np.array([1.0 / scale, 1.0 / scale, 1.0])
        self.gain = np.eye(3)
        self._pairs: list[tuple[np.ndarray, np.ndarray]] = []

    def add(self, planned: np.ndarray, observed: np.ndarray) -> None:
        """Learn from one loop: its motion (x, y, theta) planned and observed."""
        self._pairs.append((planned * self.weights, observed * self.weights))
        a = PRIOR * np.eye(3)
        b = PRIOR * np.eye(3)
        n = len(self._pairs)
        for i, (p, o) in enumerate(self._pairs):
            w = FORGET ** (n - 1 - i)
            a += w * np.outer(p, p)
            b += w * np.outer(o, p)
        self.gain = b @ np.linalg.inv(a)

    def command(self, wanted: np.ndarray) -> np.ndarray:
        """What to ask the model for so that the world moves the body by ``wanted``."""
        x = wanted * self.weights
        try:
            c = np.linalg.solve(self.gain, x)
        except np.linalg.LinAlgError:
            return wanted
        most = MOST_CORRECTION * float(np.linalg.norm(x))
        size = float(np.linalg.norm(c))
        if size > most:
            c *= most / size
        return c / self.weights
