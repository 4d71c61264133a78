"""Soak: many instantiate/reset/simulate cycles of the rover model, with and without fmpy."""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from idefix_rules.commands import Command
from idefix_rules.fmu import FmuRunner, Rock, source_dir, synthetic_terrain, write_terrain

DRIVER = Path(__file__).with_name("fmu_soak_driver.c")


@pytest.mark.slow
def test_one_thousand_cycles_in_c_succeed(tmp_path: Path) -> None:
    compiler = shutil.which("cc") or shutil.which("gcc")
    if compiler is None:
        pytest.skip("no C compiler")
    import fmpy

    headers = Path(fmpy.__file__).parent / "c-code"
    sources = source_dir() / "sources"
    binary = tmp_path / "soak"
    subprocess.run([compiler, "-std=c99", "-O2", f"-I{headers}", f"-I{sources}", str(DRIVER),
                    *map(str, sorted(sources.glob("*.c"))), "-lm", "-o", str(binary)],
                   check=True)
    terrain = write_terrain(tmp_path / "soak.terrain", synthetic_terrain(
        size=3.0, cell=0.02, roughness=0.01, seed=2,
        rocks=[Rock(0.25, -0.26, 0.05, 0.05, 0.04), Rock(0.1, 0.3, 0.04, 0.06, 0.03)]))
    result = subprocess.run([str(binary), "1000", str(terrain)], capture_output=True, text=True,
                            check=False)
    assert result.returncode == 0, result.stderr
    assert "1000 cycles ok" in result.stdout


@pytest.mark.slow
def test_two_hundred_runner_cycles_stay_identical(rover_fmu: Path) -> None:
    chain = [Command(0.05, 0.05, 0.2), Command(0.08, -0.02, 0.0)]
    with FmuRunner(rover_fmu) as runner:
        first = runner.run({"soil.cohesion": 120.0}, chain, 20.0, 0.1)
        for k in range(200):
            runner.run({"soil.cohesion": 50.0 + k}, chain, 20.0, 0.1)
        last = runner.run({"soil.cohesion": 120.0}, chain, 20.0, 0.1)
    for name in first:
        np.testing.assert_array_equal(first[name], last[name], err_msg=name)
