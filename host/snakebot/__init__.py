"""snakebot: gaits for wheeled snake robots on Dynamixel AX-12 servos, the tools that run
them on a ROBOTIS CM-530 (Protocol 1.0, uploads, flashing), and an emulated robot that
runs the real firmware.

The command line (``snakebot --help``) is a thin layer over this library. The library is
laid out in layers; each imports only from the layers below it, so the folder a name
lives in says what it may depend on:

- ``snakebot.cli``: the command line: one subpackage or module per command group; a
  command parses, calls one library function and prints.
- ``snakebot.plots``: every figure and video (matplotlib, the ``plot`` extra).
- ``snakebot.workflows``: what combines the model, the emulator and the link: the demo,
  closed-loop goto, predictions on the emulated robot, the comparison of a recorded run
  with its prediction, gait search, the thesis runs.
- ``snakebot.sim``: the emulated robot: virtual AX-12 servos on an emulated bus with
  wire timing and seeded faults, the kinematic and MuJoCo worlds, the firmware in QEMU,
  the emulated ROBOTIS bootloader, and the ``sim://`` port.
- ``snakebot.link``: operations on a port, real or ``sim://``: the Protocol 1.0 client
  (``link.transport``), the controller's operations (``link.controller``: upload,
  playback, library, monitor, drive), flashing (``link.flash``) and servo chores
  (``link.bus``). It never imports ``sim``: the emulator is only a port name to it.
- ``snakebot.model``: pure computation: robot descriptions, kinematics and their C core,
  symbolic derivations, gaits, the firmware's player and tick, programs in SI units,
  plans.
- ``snakebot.formats``: bytes only: Protocol 1.0 packets, gait tables, programs, the
  WRITEs of an upload.
- ``snakebot.facts``: what is true of the hardware, as data: device descriptions, the
  controller's control table, the boards' facts read from ``board.h``.
- the package root: ``errors`` (``SnakebotError``, the root of every error the CLI
  reports in one line), ``core`` (the C core through cffi), ``paths``, ``extras``,
  ``userfiles``, ``firmware`` (the images).

Where to start:

- ``snakebot.model.robots.load_robot``: a built-in robot (``snake5``, ``snake3``,
  ``trident``, ``car``) or your robot's .toml; ``snakebot.model.robots.schema`` says
  what each key of the file means (``snakebot robot new`` writes one to edit).
- ``snakebot.model.gait.serpenoid``: a serpenoid gait for a robot, with its predicted
  motion and the gait table the controller plays.
- ``snakebot.link.transport.DxlClient``: Protocol 1.0 to the servos on a bus adapter,
  or to emulated servos on ``sim://``.
- ``snakebot.link.controller.client.ControllerClient`` and
  ``snakebot.link.controller.upload.upload_gait``: the CM-530 running snakebot's
  firmware, over its PC link.
- ``snakebot.sim.serve.EmulatedRobot``: the firmware in QEMU with emulated servos and a
  world that moves the body; ``snakebot.workflows.demo.run_demo`` is ``snakebot demo``.
- ``snakebot.errors``: every error is an ``InputError`` (bad input) or a
  ``RuntimeFailure`` (the world did not cooperate), with a message that names the fix.

From a robot to the bytes the controller plays, and a servo read over the emulated
bus (this runs as it is, with no hardware):

>>> from math import pi, radians
>>> from snakebot.formats.gaittable import GaitTable
>>> from snakebot.link.transport import DxlClient
>>> from snakebot.model.gait import serpenoid
>>> from snakebot.model.robots import load_robot
>>> robot = load_robot("snake5")              # model: a built-in robot
>>> gait = serpenoid(robot, radians(30), 2 * pi, radians(60), cycles=1)
>>> round(gait.predicted["dx"], 2)            # metres forward in one cycle, predicted
0.63
>>> blob = gait.gait_table().encode()         # formats: what the controller stores
>>> GaitTable.decode(blob).joint_ids          # its servo IDs
(10, 11, 15, 16)
>>> with DxlClient("sim://?robot=snake5") as bus:  # link, to emulated servos (sim)
...     bus.read_u16(10, 36)                  # servo 10's Present Position, in ticks
512

The README and the documents in ``docs/`` cover the commands, the hardware, the models
and what the tests promise.
"""

__version__ = "0.1.0"
