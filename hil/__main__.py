"""`python -m hil ecu|replay ...`: the CAN link's command line (see hil.cli)."""

import sys

from hil.cli import main

sys.exit(main())
