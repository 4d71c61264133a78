"""Crash safety of the compressed results file: a writer killed (SIGKILL) at random moments,
mid-write included, leaves a file whose complete runs read back exactly, and writing the missing
runs afterwards gives the same datasets as a writer that was never killed."""

from __future__ import annotations

import random
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import pytest

from idefix_rules.campaign.storage.store import (
    STATUS_COMPLETE,
    STATUS_MISSING,
    ResultStore,
)

pytestmark = pytest.mark.slow

RUNS = 150
SAMPLES = 2000

WRITER = textwrap.dedent(f"""\
    import sys
    from pathlib import Path
    import numpy as np
    from idefix_rules.campaign.storage.store import ResultStore, STATUS_MISSING
    from idefix_rules.commands import Command

    def signals(path, run):
        rng = np.random.default_rng(1000 * path + run)
        return {{"x": np.cumsum(rng.normal(size={SAMPLES})),
                 "wheel.slip": rng.random(({SAMPLES}, 4)),
                 "command": np.repeat(np.arange(4.0), {SAMPLES} // 4)}}

    target = Path(sys.argv[1])
    if target.exists():
        store = ResultStore.open(target, writable=True)
    else:
        store = ResultStore.create(target, {{"runs": {RUNS}}}, {{"campaign": "name: k\\\\n"}})
    for index, name in enumerate(("a", "b")):
        if not store.has_path(name):
            store.create_path(name, index, [Command(0.1, 0.2, 0.0)], {{"status": "simulated"}})
        if not store.has_runs(name):
            store.allocate_runs(name, {RUNS}, {{"x": ({SAMPLES},), "wheel.slip": ({SAMPLES}, 4),
                                               "command": ({SAMPLES},)}}, {{}}, {{}})
    print("ready", flush=True)
    for run in range({RUNS}):
        for index, name in enumerate(("a", "b")):
            if store.run_status(name)[run] == STATUS_MISSING:
                if run % 17 == 5:
                    store.write_failure(name, run, f"run {{run}} crashed")
                else:
                    store.write_run(name, run, signals(index, run))
    store.close()
""")


def expected_signals(path: int, run: int) -> dict[str, np.ndarray]:
    rng = np.random.default_rng(1000 * path + run)
    return {"x": np.cumsum(rng.normal(size=SAMPLES)), "wheel.slip": rng.random((SAMPLES, 4)),
            "command": np.repeat(np.arange(4.0), SAMPLES // 4)}


def stored(path: Path) -> dict[str, np.ndarray]:
    store = ResultStore.open(path)
    try:
        found = {}
        for name in ("a", "b"):
            found[f"{name}/status"] = store.run_status(name)
            for key, values in store.read_runs(name, slice(0, RUNS)).items():
                found[f"{name}/{key}"] = values
        return found
    finally:
        store.close()


def test_a_writer_killed_at_random_moments_loses_only_runs_in_flight(tmp_path: Path) -> None:
    script = tmp_path / "writer.py"
    script.write_text(WRITER)
    whole = tmp_path / "whole.h5"
    writer = subprocess.Popen([sys.executable, str(script), str(whole)],
                              stdout=subprocess.PIPE, text=True)
    assert writer.stdout is not None and writer.stdout.readline().strip() == "ready"
    started = time.perf_counter()
    assert writer.wait(timeout=300) == 0
    writing = time.perf_counter() - started  # how long writing the runs takes here, now
    writer.stdout.close()
    reference = stored(whole)
    chooser = random.Random(12)
    killed_mid_campaign = 0
    for trial in range(5):
        target = tmp_path / f"killed-{trial}.h5"
        process = subprocess.Popen([sys.executable, str(script), str(target)],
                                   stdout=subprocess.PIPE, text=True)
        assert process.stdout is not None
        assert process.stdout.readline().strip() == "ready"  # the runs are allocated
        time.sleep(chooser.uniform(0.0, 0.9 * writing))  # somewhere in the writing of the runs
        process.send_signal(signal.SIGKILL)
        process.wait(timeout=30)
        process.stdout.close()
        store = ResultStore.open(target, writable=True)
        try:
            for index, name in enumerate(("a", "b")):
                if not store.has_runs(name):
                    continue
                status = store.run_status(name)
                killed_mid_campaign += int(np.any(status == STATUS_MISSING))
                for run in np.flatnonzero(status == STATUS_COMPLETE):
                    got = store.read_runs(name, slice(int(run), int(run) + 1))
                    for key, values in expected_signals(index, int(run)).items():
                        assert np.array_equal(got[key][0], values.astype(
                            np.float32 if key != "x" else np.float64)), (trial, name, run, key)
        finally:
            store.close()
        # resume: the same writer fills what is missing
        subprocess.run([sys.executable, str(script), str(target)], check=True, timeout=300,
                       stdout=subprocess.DEVNULL)
        again = stored(target)
        assert again.keys() == reference.keys()
        for key in reference:
            assert np.array_equal(again[key], reference[key], equal_nan=True), (trial, key)
    assert killed_mid_campaign > 0  # at least one kill really fell inside the writing
