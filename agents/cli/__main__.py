"""``python -m agents.cli``: the ``food-fetch`` command."""

import sys

from agents.cli import main

sys.exit(main())
