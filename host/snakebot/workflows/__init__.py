"""What combines the model, the emulator and the link: the demo (``demo``), closed-loop
goto (``goto``), predictions on an emulated robot (``predict``), the comparison of a run
with its prediction (``compare``), gait search (``search``) and the thesis runs
(``thesis``, ``friction``).

May import: ``sim``, ``link``, ``model``, ``formats``, ``facts`` and the package root."""
