"""``python -m staghunt`` runs the command-line interface."""

import sys

from staghunt.cli import main

if __name__ == "__main__":
    sys.exit(main())
