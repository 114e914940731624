"""`python -m mate ...`: the `mate` command (the same parser, errors and exit statuses)."""

import sys

from mate.cli.main import main

sys.exit(main())
