"""``python -m gagen.viewer``: see ``gagen.viewer.command``."""

import sys

from gagen.viewer.command import main

sys.exit(main())
