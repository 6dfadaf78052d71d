"""`python -m dynid.cli`: the same as the `dynid` command."""

import sys

from . import main

sys.exit(main())
