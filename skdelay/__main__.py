"""``python -m skdelay``: the same as the ``skdelay`` command."""

import sys

from .cli import main

if __name__ == "__main__":
    sys.exit(main())
