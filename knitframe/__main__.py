import sys

from knitframe.cli import main

sys.exit(main())
