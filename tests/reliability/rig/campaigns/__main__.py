"""``python -m tests.reliability.rig.campaigns``: every campaign, or those asked for."""

import contextlib
import sys

from tests.reliability.rig.campaigns.cli import main

with contextlib.suppress(KeyboardInterrupt):
    sys.exit(main())
