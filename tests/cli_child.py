"""The ``stickslip`` command in a child process, as a user runs it: the command line to start it."""

import sys

#: argv of ``stickslip`` run by this Python (arguments follow)
STICKSLIP = [sys.executable, "-c", "import sys\nfrom stickslip.cli import main\nsys.exit(main())"]
