"""The ``jaxfric`` command line: ``demo``, ``fit``, ``simulate``, ``compare``, ``diagnose``.

The top floor of the project: it uses `fitting` (fits, diagnosis) and `jaxfric` (models,
data), and neither of them imports it. `main` parses the arguments; `commands` does the
work of each subcommand, `demo` the built-in example, `report` the HTML page, `plots` the
figures and `_io` what they share (units, loading, atomic JSON).
"""

from .main import main as main
