"""``python -m handeye_ros.offline``: the offline tool, :mod:`handeye_ros.app.offline`."""

import sys

from .app.offline import main

if __name__ == '__main__':
    sys.exit(main())
