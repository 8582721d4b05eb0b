"""Servo chores on a Dynamixel bus: scan, register reads and writes, ID and baud changes
(``servo_ops``), calibration (``calibrate``) and the doctor's checks (``doctor``)."""
