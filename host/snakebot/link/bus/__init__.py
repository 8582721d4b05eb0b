"""Servo chores on a Dynamixel bus: scan, register reads and writes, ID and baud changes
(``scan``, ``registers``, ``ids``; the values they take and show are
:mod:`snakebot.formats.register_values`), calibration (``calibrate``) and the doctor's
checks (``doctor``).

May import: as the ``link`` layer (the other ``link`` packages, ``model``, ``formats``,
``facts``, the package root); never ``sim``.
"""
