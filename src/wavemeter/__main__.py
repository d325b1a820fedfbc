"""``python -m wavemeter``: the command line, as the ``wavemeter`` command."""

import sys

from wavemeter.cli.app import main

sys.exit(main())
