"""``python -m bowden`` runs the command line."""

import sys

from bowden.cli import main

sys.exit(main())
