"""Suite-wide settings: under CI, hypothesis runs a fixed, derandomised set of examples so a
green run is reproducible; locally it explores new examples every run (and keeps failures in
its example database)."""

import os

from hypothesis import settings

settings.register_profile("ci", derandomize=True, print_blob=True)
if os.environ.get("CI"):
    settings.load_profile("ci")

# tests/fixtures holds inputs, not tests: its case file would otherwise be collected by the
# case-file plugin (tests/testing/test_testing_frozen_cases.py runs it on purpose)
collect_ignore = ["fixtures"]
