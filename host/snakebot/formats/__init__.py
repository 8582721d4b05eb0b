"""Bytes only: what crosses a wire or lands in a file. Protocol 1.0 packets
(``protocol``), gait tables (``gaittable``), programs (``program``), the WRITEs that
upload them (``upload_writes``), and the live topics a Foxglove server streams and an
MCAP recording holds (``live_topics``, with the Foxglove layout for them).

May import: ``facts`` and the package root."""
