"""Suite-wide settings: under CI, hypothesis runs a fixed, derandomised set of examples so a
green run is reproducible; locally it explores new examples every run (and keeps failures in
its example database)."""

import os
from pathlib import Path

from hypothesis import settings

# Python subprocesses the tests start (a campaign killed mid-run, a CLI) import the checkout
# under test, not whichever copy of the package happens to be installed.
_CHECKOUT = str(Path(__file__).resolve().parents[1])
os.environ["PYTHONPATH"] = os.pathsep.join(
    [_CHECKOUT, *filter(None, os.environ.get("PYTHONPATH", "").split(os.pathsep))])

settings.register_profile("ci", derandomize=True, print_blob=True)
if os.environ.get("CI"):
    settings.load_profile("ci")

# tests/fixtures holds inputs, not tests: its case file would otherwise be collected by the
# case-file plugin (tests/testing/test_testing_frozen_cases.py runs it on purpose)
collect_ignore = ["fixtures"]
