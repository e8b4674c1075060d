import sys

from flexparcel.cli import main

sys.exit(main())
