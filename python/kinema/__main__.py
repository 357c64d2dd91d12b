"""``python -m kinema`` runs the command line (see :mod:`kinema.cli`)."""

import sys

from kinema.cli import main

sys.exit(main())
