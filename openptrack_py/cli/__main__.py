"""``python -m openptrack_py.cli``: the ``openptrack`` command without the console script."""

import sys

from openptrack_py.cli import console

sys.exit(console())
