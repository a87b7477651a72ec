"""``python -m contouring_ros.cli``: the command line (:func:`contouring_ros.cli.main`)."""
from __future__ import annotations

import sys

from . import main

sys.exit(main())
