"""``python -m fitting.cli``: the same as the ``jaxfric`` command."""

import sys

from .main import main


sys.exit(main())
