"""Shared pytest set-up."""

from hypothesis import HealthCheck, settings

# CI machines are shared and slow: no deadlines, but a fixed, generous example budget.
settings.register_profile(
    "snakebot", deadline=None, suppress_health_check=[HealthCheck.too_slow], max_examples=200
)
settings.load_profile("snakebot")


# `make test` runs the suite with `--dist loadgroup`: each test file goes whole to one
# worker (its module fixtures, such as the package check's wheel, are made once), except
# the files below, whose tests share nothing costly and are long enough together that one
# worker running the whole file would be the critical path of the run.
SPREAD_FILES = frozenset({"test_plan_goto.py", "test_plan.py", "test_physics_video.py"})


def pytest_collection_modifyitems(config, items):
    import pytest

    for item in items:
        if item.path.name not in SPREAD_FILES:
            item.add_marker(pytest.mark.xdist_group(item.nodeid.split("::", 1)[0]))
