"""``python -m multilayer``: the command line."""

import sys

from multilayer.app.cli import main

sys.exit(main())
