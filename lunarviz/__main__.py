"""``python -m lunarviz`` is the ``lunarviz`` command."""

import sys

from .cli import main

sys.exit(main())
