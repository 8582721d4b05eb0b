"""Bytes only: what crosses a wire or lands in a file. Protocol 1.0 packets
(``protocol``), gait tables (``gaittable``), programs (``program``) and the WRITEs that
upload them (``upload_writes``).

May import: ``facts`` and the package root."""
