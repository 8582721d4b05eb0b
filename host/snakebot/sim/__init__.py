"""snakebot.sim: an emulated Dynamixel bus of virtual AX-12 servos, and the world they drive.

The pieces: ``servo`` (a virtual AX-12), ``bus`` (the wire and its virtual clock),
``faults`` (seeded fault injection), ``options`` (what a URL or the command line asks
for), ``transports`` (pseudo-terminal and Unix-socket servers), ``world`` (the body the
servos move). The ``sim://`` pyserial URL handler is registered in one place,
:mod:`snakebot.link.transport.ports`, which every snakebot port opener imports.
"""
