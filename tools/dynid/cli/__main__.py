"""`python -m dynid.cli.main`: the same as the `dynid` command."""

import sys

from . import main

sys.exit(main())
