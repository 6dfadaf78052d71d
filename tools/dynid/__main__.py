"""`python -m dynid`: the same as the `dynid` command."""

import sys

from .cli import main

sys.exit(main())
