"""The reliability rig: the fault campaigns on the firmware on both emulated boards (the
CM-530's image on the emulated STM32F103RE, the qemu build under QEMU: ``campaigns``) and
the measurement of wrong values through a damaged wire (``wrong_values``).

Both are test rigs, not part of the package: the tests in ``tests/reliability`` and
``tests/firmware`` import them, and each runs on its own from the repository root::

    python -m tests.reliability.rig.campaigns --help
    python -m tests.reliability.rig.wrong_values --help

``tests`` and ``tests/reliability`` have no ``__init__.py`` (pytest imports the test
files by their own names), so Python reads them as namespace packages; only this folder
is a package. The rig may import anything in ``snakebot`` and the test support modules
in ``tests/support``.
"""
