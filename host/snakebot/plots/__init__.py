"""Every figure snakebot draws (matplotlib with the Agg backend, no display needed) and
its videos: gaits (``gait``), predictions (``predict``), goto runs (``goto``), search
results (``search``), runs against their prediction (``compare``), the thesis studies
(``thesis``) and the top-view video (``video``).

May import: ``workflows`` and every layer below it."""
