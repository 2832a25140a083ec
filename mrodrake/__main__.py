"""``python -m mrodrake``: same as the ``mrodrake`` command."""

import sys

from mrodrake.cli import main

sys.exit(main())
