"""Deprecated: ``python -m factory.scenes.assets`` runs ``python -m factory.assets``."""

import sys

from factory.assets.__main__ import main

if __name__ == "__main__":
    sys.exit(main())
