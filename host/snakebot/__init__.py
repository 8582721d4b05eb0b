"""snakebot: gaits, Protocol 1.0 tooling and firmware support for wheeled snake robots."""

__version__ = "0.1.0"
