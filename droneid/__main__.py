import sys

from droneid.cli import main

sys.exit(main())
