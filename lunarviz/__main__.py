"""``python -m lunarviz`` is the ``lunarviz`` command."""

import sys

from lunarviz.cli import main

sys.exit(main())
