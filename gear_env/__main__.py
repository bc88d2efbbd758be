"""``python -m gear_env`` runs the ``gear-env`` command."""

import sys

from .cli import main

sys.exit(main())
