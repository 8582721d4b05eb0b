"""Pure computation on the robot: robot descriptions (``robots``), kinematics and their
C core (``kinematics``), symbolic derivations (``symbolic``), gaits (``gait``), the
firmware's player and tick (``player``), programs in SI units (``program_spec``,
``program_goals``, ``motion``) and the planners (``plan``). No ports, no emulator.

May import: ``formats``, ``facts`` and the package root."""
