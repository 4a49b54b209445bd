import sys

from crgpr.cli import main

sys.exit(main())
