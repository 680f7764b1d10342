"""``python -m freqid_casadi`` runs the ``freqid`` command line (layer L6)."""

import sys

from .cli.app import main

if __name__ == "__main__":
    sys.exit(main())
