"""pyserial URL handlers of the emulator: ``sim://`` (module ``protocol_sim``).

``import snakesim`` adds this package to ``serial.protocol_handler_packages``, after
which ``serial.serial_for_url("sim://...")`` opens an emulated bus.
"""
