import sys

from idefix_rules.cli import process_main

sys.exit(process_main())
