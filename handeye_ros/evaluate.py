"""``python -m handeye_ros.evaluate``: many recordings, :mod:`handeye_ros.app.evaluate`."""

import sys

from .app.evaluate import main

if __name__ == '__main__':
    sys.exit(main())
