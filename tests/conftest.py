"""Shared pytest set-up."""

from hypothesis import HealthCheck, settings

# CI machines are shared and slow: no deadlines, but a fixed, generous example budget.
settings.register_profile(
    "snakebot", deadline=None, suppress_health_check=[HealthCheck.too_slow], max_examples=200
)
settings.load_profile("snakebot")
