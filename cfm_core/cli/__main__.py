"""``python -m cfm_core.cli ...``: the ``cfm`` command."""

import sys

from .app import main

sys.exit(main())
