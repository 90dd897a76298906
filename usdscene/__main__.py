import sys

from usdscene.cli import main

sys.exit(main())
