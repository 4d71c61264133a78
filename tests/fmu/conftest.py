"""Shared fixtures of the rover FMU tests: one built FMU and one runner per session."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest

from idefix_rules.fmu import FmuRunner, build_fmu


@pytest.fixture(scope="session")
def rover_fmu(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The rover FMU built from the current sources (into a session cache)."""
    return build_fmu(output=tmp_path_factory.mktemp("fmu") / "idefix_rover.fmu", force=True)


@pytest.fixture(scope="session")
def rover(rover_fmu: Path) -> Iterator[FmuRunner]:
    """A runner of the rover FMU with the per-wheel normal loads as extra outputs."""
    runner = FmuRunner(rover_fmu, extra_outputs=[f"wheel.{w}.load" for w in ("FL", "FR", "RL",
                                                                              "RR")])
    yield runner
    runner.close()


@pytest.fixture(scope="session")
def unicycle_fmu(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """An FMI 2.0 co-simulation FMU exported by pythonfmu (tests/fmu/foreign_fmus.py)."""
    from foreign_fmus import build_unicycle

    return build_unicycle(tmp_path_factory.mktemp("unicycle"))


@pytest.fixture(scope="session")
def announcer_fmu(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """An FMI 2.0 FMU exported by pythonfmu that reports -1 (and idle) before it starts."""
    from foreign_fmus import build_announcer

    return build_announcer(tmp_path_factory.mktemp("announcer"))


@pytest.fixture(scope="session")
def diff_drive_fmu(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """An FMI 3.0 co-simulation FMU exported by pythonfmu3 (tests/fmu/foreign_fmus.py)."""
    from foreign_fmus import build_diff_drive

    return build_diff_drive(tmp_path_factory.mktemp("diff-drive"))


@pytest.fixture(scope="session")
def planar_me_fmu(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """An FMI 3.0 model-exchange-only FMU exported by pythonfmu3."""
    from foreign_fmus import build_planar_me

    return build_planar_me(tmp_path_factory.mktemp("planar-me"))
