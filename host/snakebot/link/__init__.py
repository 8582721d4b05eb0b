"""Operations on a port, real or ``sim://``: the Protocol 1.0 client (``transport``), the
controller's operations (``controller``: upload, playback, library, monitor, drive),
flashing through the ROBOTIS bootloader (``flash``) and servo chores (``bus``: scan,
registers, IDs, calibration, the doctor's checks).

May import: ``model``, ``formats``, ``facts`` and the package root; never ``sim``: the
emulator is reached only through a port name, like any device."""
