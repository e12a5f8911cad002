"""``python3 -m smoothffd``: see smoothffd.cli."""
import sys

from .cli import main

sys.exit(main())
