"""`python -m vsgl_addon COMMAND ...` (see vsgl_addon/cli.py)."""

import sys

from .cli import main

sys.exit(main())
