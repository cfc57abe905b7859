import sys

from terratheme.app.cli import main

sys.exit(main())
