"""Suite-wide settings: under CI, hypothesis runs a fixed, derandomised set of examples so a
green run is reproducible, then (.ci/run) the property tests once more from a printed random
seed; locally it explores new examples every run (and keeps failures in its example
database)."""

import os
from pathlib import Path

from hypothesis import settings

# Python subprocesses the tests start (a campaign killed mid-run, a CLI) import the checkout
# under test, not whichever copy of the package happens to be installed.
_CHECKOUT = str(Path(__file__).resolve().parents[1])
os.environ["PYTHONPATH"] = os.pathsep.join(
    [_CHECKOUT, *filter(None, os.environ.get("PYTHONPATH", "").split(os.pathsep))])

# pytest-xdist's workers inherit COLUMNS=80 and LINES=24 from execnet; the console (and every
# CLI the tests start) would then wrap at 80 columns instead of a log's 150
# (idefix_rules/cli/console.py). Tests that want a width set it themselves.
if os.environ.get("PYTEST_XDIST_WORKER"):
    for _inherited in ("COLUMNS", "LINES"):
        os.environ.pop(_inherited, None)

settings.register_profile("ci", derandomize=True, print_blob=True)
# The second run of the property tests in CI (.ci/run): new examples drawn from the seed given
# with --hypothesis-seed, which .ci/run prints; no example database, so that seed alone replays
# a failure anywhere (docs/ci.md). --hypothesis-profile is applied after this file is loaded.
settings.register_profile("random-seed", derandomize=False, print_blob=True, database=None)
if os.environ.get("CI"):
    settings.load_profile("ci")

# tests/fixtures holds inputs, not tests: its case file would otherwise be collected by the
# case-file plugin (tests/testing/test_testing_frozen_cases.py runs it on purpose)
collect_ignore = ["fixtures"]
