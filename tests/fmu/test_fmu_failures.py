"""FmuRunner after the FMU reported an error (FMI 2.0.x section 2.1.3): after fmi2Error the
instance is only freed (the toy FMU refuses fmi2Terminate then, as FMUs of common exporters do)
and a fresh instance in the same process runs as any; after fmi2Fatal nothing of the FMU is
called again in that process, for any instance, so the run after it is refused, not simulated
by a corrupted library (the toy's fatal fault makes every later step in the process slip more).

Each case runs in a forked child, as campaign workers do: the fatal one leaves its process with
the toy's library corrupted."""

from __future__ import annotations

import multiprocessing
import sys
from pathlib import Path
from typing import Any

import pytest

from idefix_rules.commands import Command
from idefix_rules.fmu import extract_fmu

# The toy FMU builder lives with the campaign tests; import it by name from there.
sys.path.insert(0, str(Path(__file__).parents[1] / "campaign"))

from campaign_toy_fmu import build_toy_fmu

CHAIN = [Command(0.1, 0.1, 0.0)]


@pytest.fixture(scope="module")
def toy(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    """The campaign tests' toy FMU and the folder it is extracted to once (as a campaign
    does, so that every runner loads the same library file)."""
    fmu = build_toy_fmu(tmp_path_factory.mktemp("toy"))
    return fmu, extract_fmu(fmu, tmp_path_factory.mktemp("toy-unzipped"))


def _after(fmu: Path, unzipped: Path, fault: str) -> dict[str, Any]:
    """A run that fails with ``fault`` at 2 s, then what closing its runner and a new runner's
    run (in the same process, the same library) give."""
    from idefix_rules.fmu import FmuRunner

    def said(action: Any) -> Any:
        try:
            return action()
        except Exception as failure:  # sent back as text: FMU errors need not pickle
            return f"{type(failure).__name__}: {failure}"

    runner = FmuRunner(fmu, unzipped=unzipped)
    failure = said(lambda: runner.run({fault: 2.0}, CHAIN, 20.0, 0.5))
    fatal = said(lambda: runner.fatal)
    closed = said(runner.close)

    def again() -> float:
        with FmuRunner(fmu, unzipped=unzipped) as fresh:
            return float(fresh.run({"toy.slip": 0.1}, CHAIN, 20.0, 0.5)["wheel.slip"].max())

    return {"failure": failure, "fatal": fatal, "closed": closed, "again": said(again)}


def after(toy: tuple[Path, Path], fault: str) -> dict[str, Any]:
    with multiprocessing.get_context("fork").Pool(1) as pool:
        return pool.apply(_after, (*toy, fault))


def test_after_an_error_the_instance_is_freed_and_a_fresh_one_runs_in_the_same_process(
        toy: tuple[Path, Path]) -> None:
    assert after(toy, "toy.error_at") == {
        "failure": "InfrastructureError: toy.fmu: fmi2DoStep failed at t = 1.5 s (status 3); "
                   "the FMU logged no reason",
        "fatal": False, "closed": None, "again": pytest.approx(0.1)}


def test_after_a_fatal_error_nothing_of_the_fmu_is_called_again_in_the_process(
        toy: tuple[Path, Path]) -> None:
    assert after(toy, "toy.fatal_at") == {
        "failure": "InfrastructureError: toy.fmu: fmi2DoStep failed at t = 1.5 s (status 4): "
                   "toy: slip table corrupted at t = 2 s",
        "fatal": True, "closed": None,
        "again": "InfrastructureError: toy.fmu: cannot instantiate (it returned Fatal in this "
                 "process before, and FMI allows no further call of it here)"}


def _model_exchange_fatal(fmu: Path) -> tuple[str, bool]:
    """A model-exchange run whose FMU fails Fatal inside the solver's derivative callback."""
    from fmpy.fmi1 import FMICallException
    from fmpy.fmi3 import FMU3Model

    from idefix_rules.fmu import FmuRunner

    original = FMU3Model.getContinuousStateDerivatives
    calls = [0]

    def failing(self: Any, *args: Any, **kwargs: Any) -> Any:
        calls[0] += 1
        if calls[0] > 50:  # well into the run: the solver has stepped before
            raise FMICallException("fmi3GetContinuousStateDerivatives", 4)
        return original(self, *args, **kwargs)

    FMU3Model.getContinuousStateDerivatives = failing  # type: ignore[method-assign]
    runner = FmuRunner(fmu, signal_map={"px": "x", "py": "y", "psi": "yaw"},
                       chain_delivery="inputs",
                       chain_inputs={"v": "body.speed", "w": "body.yaw_rate"})
    try:
        runner.run({}, CHAIN, 20.0, 0.5)
    except Exception as failure:  # sent back as text: FMU errors need not pickle
        return f"{type(failure).__name__}: {failure}", runner.fatal
    return "no failure", runner.fatal


def test_a_model_exchange_run_failing_inside_the_solver_is_taken_as_fatal(
        planar_me_fmu: Path) -> None:
    # fmpy's CVode calls the FMU's derivatives from a C callback: a Fatal status raised there
    # is swallowed (ctypes prints it) and the solver fails with its own error, so the status
    # never reaches the runner. The process cannot know whether the FMU returned Fatal: it is
    # taken as corrupted (the campaign's worker then ends and a fresh one takes the next run).
    with multiprocessing.get_context("fork").Pool(1) as pool:
        failure, fatal = pool.apply(_model_exchange_fatal, (planar_me_fmu,))
    assert failure.startswith("InfrastructureError: PlanarME.fmu: model exchange simulation "
                              "failed (CVode error"), failure
    assert "at the first call" not in failure  # the precondition: it failed mid-run
    assert fatal is True


def _model_exchange_error(fmu: Path) -> tuple[str, bool, list[str]]:
    """A model-exchange run whose FMU returns Error (not Fatal) where fmpy calls it from
    Python (reading an output): what the runner raised, whether it took the process as
    corrupted, and the FMI calls made on the instance after the failure."""
    from fmpy.fmi1 import FMICallException
    from fmpy.fmi3 import FMU3Model

    from idefix_rules.fmu import FmuRunner

    original = FMU3Model.getFloat64
    calls = [0]
    after: list[str] = []

    def failing(self: Any, *args: Any, **kwargs: Any) -> Any:
        calls[0] += 1
        if calls[0] > 20:
            raise FMICallException("fmi3GetFloat64", 3)  # fmi3Error
        return original(self, *args, **kwargs)

    freeing = FMU3Model.freeInstance

    def free(self: Any) -> None:
        after.append("freeInstance")
        freeing(self)

    FMU3Model.getFloat64 = failing  # type: ignore[method-assign]
    FMU3Model.freeInstance = free  # type: ignore[method-assign]
    runner = FmuRunner(fmu, signal_map={"px": "x", "py": "y", "psi": "yaw"},
                       chain_delivery="inputs",
                       chain_inputs={"v": "body.speed", "w": "body.yaw_rate"})
    try:
        runner.run({}, CHAIN, 20.0, 0.5)
    except Exception as failure:  # sent back as text: FMU errors need not pickle
        return f"{type(failure).__name__}: {failure}", runner.fatal, after
    return "no failure", runner.fatal, after


def test_a_model_exchange_run_failing_with_error_frees_its_instance(
        planar_me_fmu: Path) -> None:
    """fmpy frees a model-exchange instance it made only when the run succeeds: each run that
    failed with Error left one allocated in the worker, which runs on. The instance is the
    runner's own now, freed after an Error (FMI allows it), and the process goes on."""
    with multiprocessing.get_context("fork").Pool(1) as pool:
        failure, fatal, after = pool.apply(_model_exchange_error, (planar_me_fmu,))
    assert failure.startswith("InfrastructureError: PlanarME.fmu: model exchange simulation "
                              "failed"), failure
    assert fatal is False
    assert after == ["freeInstance"]
