import sys

from idefix_rules.cli import main

sys.exit(main())
