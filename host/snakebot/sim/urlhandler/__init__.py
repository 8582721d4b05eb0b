"""pyserial URL handlers of the emulator: ``sim://`` (module ``protocol_sim``).

:mod:`snakebot.link.transport.ports` adds this package to ``serial.protocol_handler_packages``
(the one registration), after which ``serial.serial_for_url("sim://...")`` opens an
emulated bus.

May import: as the ``sim`` layer (``sim.bus``, ``sim.options``, the layers below).
"""
