"""snakebot.sim: the emulated robot, for tests, the demo and anyone without hardware.

The pieces: ``servo`` (the virtual AX-12: its registers and motor, the reference model
in Python and the fast one with its hot path in C), ``bus`` (the emulated bus: its
virtual clock, the wire and its timing, seeded faults), ``world`` and ``physics`` (the
body the servos move: the kinematic world and the MuJoCo one), ``options`` (what a URL
or the command line asks for), ``state``, ``transports`` (pseudo-terminal and
Unix-socket servers), ``urlhandler`` (the ``sim://`` port), ``controller_pty`` (an
emulated controller in Python), ``qemu`` (the real firmware under QEMU), ``serve``
(the robot behind the firmware, as ``snakebot sim serve`` runs it), ``bootloader``
(the emulated ROBOTIS bootloader) and ``workdirs``. The ``sim://`` pyserial URL handler
is registered in one place, :mod:`snakebot.link.transport.ports`, which every snakebot
port opener imports.

May import: ``link`` (as a bus master uses a port: ``link.transport``), ``model``,
``formats``, ``facts`` and the package root. Nothing below ``workflows`` imports it.
"""
