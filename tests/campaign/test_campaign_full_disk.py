"""A full disk at every stage of a campaign: exit 3 with one line naming the folder and the
free and needed space, no traceback, a results file whose simulated datasets all read back,
and, once space is freed, ``--resume`` / ``evaluate`` giving what an undisturbed run gives.

The campaigns run on a 40 MB tmpfs (mounted here as root; a loop-mounted ext4 image where
tmpfs is refused; skipped where neither can be mounted) filled by a file that leaves just
the room measured to reach the stage under test. Where a stage's own free-space check would
stop it before it writes, a variant makes its estimate zero (in the subprocess only) so the
disk really fills while the stage writes.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import textwrap
import uuid
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import h5py
import numpy as np
import pytest
from campaign_texts import CAMPAIGN, RULEBOOK
from dataset_digest import results_digest

from idefix_rules.campaign.storage.diskspace import MARGIN

pytestmark = pytest.mark.slow

RUNS = 200
TEXT = CAMPAIGN.replace("runs: 6", f"runs: {RUNS}")
DISK = "40m"


@dataclass(frozen=True)
class Outcome:
    code: int
    stdout: str
    stderr: str


def _try(*command: str) -> bool:
    return subprocess.run(command, capture_output=True).returncode == 0


@pytest.fixture
def small_disk(tmp_path: Path) -> Iterator[Path]:
    """A 40 MB file system of its own, unmounted afterwards."""
    mount = tmp_path / "disk"
    mount.mkdir()
    if not (hasattr(os, "geteuid") and os.geteuid() == 0):
        pytest.skip("mounting a small file system needs root (CI runs these as root)")
    if not _try("mount", "-t", "tmpfs", "-o", f"size={DISK}", "tmpfs", str(mount)):
        image = tmp_path / "disk.img"
        with image.open("wb") as handle:
            handle.truncate(40 * 1024 * 1024)
        if not (_try("mkfs.ext4", "-q", "-F", str(image))
                and _try("mount", "-o", "loop", str(image), str(mount))):
            pytest.skip("neither a tmpfs nor a loop device can be mounted here")
    try:
        yield mount
    finally:
        if not _try("umount", str(mount)):
            _try("umount", "-l", str(mount))


def _free(folder: Path) -> int:
    stats = os.statvfs(folder)
    return stats.f_bavail * stats.f_frsize


def fill(disk: Path, leave: int) -> Path:
    """A file taking all free space of ``disk`` but ``leave`` bytes."""
    filler = disk / "filler"
    with filler.open("wb") as handle:
        block = bytes(1 << 20)
        while _free(disk) - leave >= len(block):
            handle.write(block)
            handle.flush()
        rest = _free(disk) - leave
        if rest > 0:
            handle.write(bytes(rest))
        handle.flush()
        os.fsync(handle.fileno())
    return filler


def place_campaign(folder: Path, toy_fmu: Path) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    shutil.copyfile(toy_fmu, folder / "toy.fmu")
    (folder / "test.rules").write_text(RULEBOOK)
    (folder / "campaign.yaml").write_text(TEXT)
    return folder / "campaign.yaml"


def cli(*args: str, cwd: Path, patch: str = "") -> Outcome:
    """``idefix-verify ARGS`` in a process of its own (after ``patch``, Python run first)."""
    code = textwrap.dedent(patch) + textwrap.dedent(f"""
        import sys
        from idefix_rules.cli import main
        sys.exit(main({list(args)!r}))
    """)
    done = subprocess.run([sys.executable, "-c", code], cwd=cwd, capture_output=True,
                          text=True, timeout=600)
    return Outcome(done.returncode, done.stdout, done.stderr)


def evaluation_arrays(results: Path) -> dict[str, np.ndarray]:
    """The per-run arrays of the evaluation (not its times), to compare two files."""
    found: dict[str, np.ndarray] = {}
    with h5py.File(results, "r") as file:
        for path in file["paths"]:
            group = file["paths"][path].get("evaluation")
            if group is None:
                continue

            def keep(name: str, item: object, prefix: str = path) -> None:
                if isinstance(item, h5py.Dataset):
                    found[f"{prefix}/{name}"] = item[()]

            group.visititems(keep)
        found["ranking"] = np.array(json.loads(file["evaluation"].attrs["ranking"]))
    return found


def assert_same_evaluation(got: dict[str, np.ndarray], expected: dict[str, np.ndarray]) -> None:
    assert got.keys() == expected.keys()
    for key, values in expected.items():
        if values.dtype.kind == "f":
            assert np.array_equal(got[key], values, equal_nan=True), key
        else:
            assert np.array_equal(got[key], values), key


def assert_one_clear_line(outcome: Outcome, folder: Path) -> str:
    """Exit 3, no traceback anywhere, and exactly one line on stderr: the full disk, the
    folder, what is free and what is needed."""
    shown = outcome.stdout + outcome.stderr
    assert outcome.code == 3, shown
    assert "Traceback" not in shown, shown
    lines = [line for line in outcome.stderr.splitlines() if line.strip()]
    assert len(lines) == 1, shown
    [line] = lines
    assert line.startswith(f"disk full: {folder} has "), line
    assert " MB free, " in line and " needed to " in line, line
    return line


def assert_simulated_data_readable(results: Path) -> None:
    """The file opens with h5py and every dataset outside the evaluation reads back."""
    if not results.exists():
        return
    with h5py.File(results, "r") as file:
        names: list[str] = []
        file.visit(names.append)
        for name in names:
            item = file[name]
            if isinstance(item, h5py.Dataset) and "/evaluation/" not in f"/{name}/":
                item[()]


@dataclass(frozen=True)
class Undisturbed:
    """The campaign run without a disk problem: its datasets, and what each stage wrote."""

    digest: str
    evaluation: dict[str, np.ndarray]
    terrain: int
    results: int
    report: int


@pytest.fixture(scope="module")
def undisturbed(tmp_path_factory: pytest.TempPathFactory, toy_fmu: Path) -> Undisturbed:
    folder = tmp_path_factory.mktemp("undisturbed")
    place_campaign(folder, toy_fmu)
    outcome = cli("campaign.yaml", "--quiet", cwd=folder)
    assert outcome.code == 1, outcome.stdout + outcome.stderr
    out = folder / "out"
    report = sum(path.stat().st_size for path in out.iterdir()
                 if path.suffix in (".html", ".png"))
    return Undisturbed(results_digest(out / "results.h5"), evaluation_arrays(out / "results.h5"),
                       (out / "terrain.dem").stat().st_size,
                       (out / "results.h5").stat().st_size, report)


def _recover(folder: Path, undisturbed: Undisturbed, command: tuple[str, ...]) -> None:
    """After the filler is gone, ``command`` completes and the datasets are the undisturbed
    run's."""
    outcome = cli(*command, cwd=folder)
    assert outcome.code == 1, outcome.stdout + outcome.stderr
    assert "Traceback" not in outcome.stdout + outcome.stderr
    results = folder / "out" / "results.h5"
    assert results_digest(results) == undisturbed.digest
    assert_same_evaluation(evaluation_arrays(results), undisturbed.evaluation)
    assert not list((folder / "out").glob(".results.h5.*"))  # no new version left behind


RESUME = ("campaign.yaml", "--quiet", "--resume")


def test_a_disk_full_before_the_runs_are_allocated(small_disk: Path, toy_fmu: Path,
                                                   undisturbed: Undisturbed) -> None:
    terrain = undisturbed.terrain
    folder = small_disk / "campaign"
    place_campaign(folder, toy_fmu)
    # room for the terrain, the results file's header and the reference runs, not the runs
    filler = fill(small_disk, terrain + MARGIN + 200_000)
    outcome = cli("campaign.yaml", "--quiet", cwd=folder)
    line = assert_one_clear_line(outcome, folder / "out")
    assert "--resume" in line
    assert_simulated_data_readable(folder / "out" / "results.h5")
    filler.unlink()
    _recover(folder, undisturbed, RESUME)


def test_a_disk_full_before_the_monte_carlo_runs_are_simulated(
        small_disk: Path, toy_fmu: Path, undisturbed: Undisturbed) -> None:
    terrain, results = undisturbed.terrain, undisturbed.results
    folder = small_disk / "campaign"
    place_campaign(folder, toy_fmu)
    filler = fill(small_disk, terrain + MARGIN + results * 2 // 3)  # the runs do not fit
    outcome = cli("campaign.yaml", "--quiet", cwd=folder)
    line = assert_one_clear_line(outcome, folder / "out")
    assert f"needed to store the {2 * RUNS} runs still to simulate" in line
    assert_simulated_data_readable(folder / "out" / "results.h5")
    filler.unlink()
    _recover(folder, undisturbed, RESUME)


def filled_after(target: str, calls: int, disk: Path, leave: int) -> str:
    """Patch code: another program fills ``disk`` (all but ``leave`` bytes) right before the
    ``calls``-th call of ``target`` (``module:Class.method``) goes on."""
    module, attribute = target.split(":")
    owner, method = attribute.split(".")
    return f"""
        import os
        from {module} import {owner}
        _original = {owner}.{method}
        _calls = [0]
        def _filling(*args, **kwargs):
            _calls[0] += 1
            if _calls[0] == {calls}:
                with open({str(disk / "filler")!r}, "ab") as handle:
                    while True:
                        stats = os.statvfs({str(disk)!r})
                        free = stats.f_bavail * stats.f_frsize - {leave}
                        if free <= 0:
                            break
                        try:
                            handle.write(bytes(min(free, 1 << 20)))
                            handle.flush()
                        except OSError:
                            break
            return _original(*args, **kwargs)
        {owner}.{method} = _filling
    """


def test_a_disk_filling_up_while_runs_are_stored(small_disk: Path, toy_fmu: Path,
                                                 undisturbed: Undisturbed) -> None:
    folder = small_disk / "campaign"
    place_campaign(folder, toy_fmu)
    # another program takes the disk once 150 runs are stored: the next ones meet it
    outcome = cli("campaign.yaml", "--quiet", cwd=folder, patch=filled_after(
        "idefix_rules.campaign.storage.store:ResultStore.write_run", 151, small_disk, 8192))
    line = assert_one_clear_line(outcome, folder / "out")
    assert "needed to store the" in line and "--resume" in line
    results_file = folder / "out" / "results.h5"
    assert_simulated_data_readable(results_file)
    with h5py.File(results_file, "r") as file:
        stored = sum(int(np.sum(file[f"paths/{name}/runs/status"][()] != 0))
                     for name in ("straight", "arc"))
    # the disk really filled while runs were being stored (a few runs still fit in what the
    # filler leaves: 160 since format 5 stores z and energy in float32, 150-159 before)
    assert 150 <= stored < 165
    filler = small_disk / "filler"
    # evaluating the interrupted file on the full disk: refused, the file untouched
    before = results_file.read_bytes()
    outcome = cli("evaluate", str(results_file), cwd=folder)
    assert_one_clear_line(outcome, folder / "out")
    assert results_file.read_bytes() == before
    filler.unlink()
    _recover(folder, undisturbed, RESUME)


def test_a_disk_without_any_free_space(small_disk: Path, toy_fmu: Path,
                                       undisturbed: Undisturbed) -> None:
    folder = small_disk / "campaign"
    place_campaign(folder, toy_fmu)
    assert cli("campaign.yaml", "--quiet", "--no-report", cwd=folder).code == 1
    results = folder / "out" / "results.h5"
    before = results.read_bytes()
    filler = fill(small_disk, 0)
    for command in (("campaign.yaml", "--quiet", "--resume"), ("evaluate", str(results)),
                    ("campaign.yaml", "--quiet")):
        assert_one_clear_line(cli(*command, cwd=folder), folder / "out")
    assert results.read_bytes() == before
    filler.unlink()
    _recover(folder, undisturbed, RESUME)


def test_a_disk_full_when_the_evaluation_starts(small_disk: Path, toy_fmu: Path,
                                                undisturbed: Undisturbed) -> None:
    terrain, results = undisturbed.terrain, undisturbed.results
    folder = small_disk / "campaign"
    place_campaign(folder, toy_fmu)
    filler = fill(small_disk, terrain + MARGIN + results + 1_000_000)  # simulated, no copy
    outcome = cli("campaign.yaml", "--quiet", cwd=folder)
    line = assert_one_clear_line(outcome, folder / "out")
    assert "to write the evaluation into results.h5" in line
    results_file = folder / "out" / "results.h5"
    assert_simulated_data_readable(results_file)
    with h5py.File(results_file, "r") as file:
        assert file.attrs["state"] == "complete"
        assert "evaluation" not in file
    assert results_digest(results_file) == undisturbed.digest
    # evaluate on the same full disk: refused the same way, the file untouched
    before = results_file.read_bytes()
    outcome = cli("evaluate", str(results_file), cwd=folder)
    assert_one_clear_line(outcome, folder / "out")
    assert results_file.read_bytes() == before
    filler.unlink()
    _recover(folder, undisturbed, ("evaluate", str(results_file)))


NO_COPY_ESTIMATE = """
    from idefix_rules.campaign.storage.revision import Revision
    Revision.needed = lambda self, extra: 0  # the checks pass: the copy fills the disk
"""


def test_a_disk_filling_up_while_the_evaluation_is_written(
        small_disk: Path, toy_fmu: Path, undisturbed: Undisturbed) -> None:
    terrain, results = undisturbed.terrain, undisturbed.results
    folder = small_disk / "campaign"
    place_campaign(folder, toy_fmu)
    filler = fill(small_disk, terrain + MARGIN + results + 1_000_000)
    outcome = cli("campaign.yaml", "--quiet", cwd=folder, patch=NO_COPY_ESTIMATE)
    assert_one_clear_line(outcome, folder / "out")
    results_file = folder / "out" / "results.h5"
    assert_simulated_data_readable(results_file)
    assert not list((folder / "out").glob(".results.h5.*"))  # the new version is dropped
    filler.unlink()
    # evaluated once, then evaluated again on a disk that fills during the copy
    assert cli("evaluate", str(results_file), cwd=folder).code == 1
    evaluated = results_file.read_bytes()
    filler = fill(small_disk, MARGIN + 200_000)
    outcome = cli("evaluate", str(results_file), cwd=folder, patch=NO_COPY_ESTIMATE)
    assert_one_clear_line(outcome, folder / "out")
    assert results_file.read_bytes() == evaluated  # the previous evaluation stays whole
    assert_same_evaluation(evaluation_arrays(results_file), undisturbed.evaluation)
    filler.unlink()
    _recover(folder, undisturbed, RESUME)


def test_a_disk_full_when_the_report_is_written(small_disk: Path, toy_fmu: Path,
                                                undisturbed: Undisturbed) -> None:
    terrain, results = undisturbed.terrain, undisturbed.results
    folder = small_disk / "campaign"
    place_campaign(folder, toy_fmu)
    # room to simulate and evaluate (a copy of the results while it is written), not more
    filler = fill(small_disk, terrain + MARGIN + 2 * results + 1_200_000)
    outcome = cli("campaign.yaml", "--quiet", cwd=folder)
    line = assert_one_clear_line(outcome, folder / "out")
    assert "to write report.html and its figures" in line
    assert "idefix-verify report" in line
    out = folder / "out"
    assert (out / "summary.json").exists() and not (out / "report.html").exists()
    assert results_digest(out / "results.h5") == undisturbed.digest
    outcome = cli("report", str(out / "results.h5"), cwd=folder)
    assert_one_clear_line(outcome, out)
    filler.unlink()
    assert cli("report", str(out / "results.h5"), cwd=folder).code == 0
    assert (out / "report.html").exists()
    _recover(folder, undisturbed, RESUME)


NO_REPORT_ESTIMATE = """
    # as if another program filled the disk: the check passes, the report meets a full disk
    import idefix_rules.campaign.storage.diskspace as diskspace
    import idefix_rules.campaign.runner as runner
    runner.REPORT_BYTES = runner.REPORT_BYTES_PER_PATH = diskspace.MARGIN = 0
"""


def test_a_disk_filling_up_while_the_report_is_written(
        small_disk: Path, toy_fmu: Path, undisturbed: Undisturbed) -> None:
    report = undisturbed.report
    folder = small_disk / "campaign"
    place_campaign(folder, toy_fmu)
    assert cli("campaign.yaml", "--quiet", "--no-report", cwd=folder).code == 1
    out = folder / "out"
    filler = fill(small_disk, report // 3)
    outcome = cli("report", str(out / "results.h5"), cwd=folder, patch=NO_REPORT_ESTIMATE)
    assert_one_clear_line(outcome, out)
    assert not (out / "report.html").exists()
    assert not [path for path in out.iterdir() if path.name.endswith(".tmp")]
    filler.unlink()
    assert cli("report", str(out / "results.h5"), cwd=folder).code == 0


def test_a_disk_full_when_summary_json_is_written(small_disk: Path, toy_fmu: Path,
                                                  undisturbed: Undisturbed) -> None:
    folder = small_disk / "campaign"
    place_campaign(folder, toy_fmu)
    assert cli("campaign.yaml", "--quiet", "--no-report", cwd=folder).code == 1
    out = folder / "out"
    # the evaluation is swapped in, then the disk is full for summary.json
    patch = filled_after("idefix_rules.campaign.outcome:outputs.write_summary", 1, small_disk,
                         0)
    outcome = cli("evaluate", str(out / "results.h5"), cwd=folder, patch=patch)
    line = assert_one_clear_line(outcome, out)
    assert "to write summary.json" in line
    assert not (out / "summary.json").exists()
    assert_simulated_data_readable(out / "results.h5")
    (small_disk / "filler").unlink()
    _recover(folder, undisturbed, ("evaluate", str(out / "results.h5")))


def test_planning_a_million_runs_writes_almost_nothing_before_the_first_run(
        tmp_path: Path, toy_fmu: Path) -> None:
    """Runs are allocated a block at a time: stopped right after the allocation (as Ctrl-C
    would stop it), a campaign planning 1,000,000 runs has written well under 1 MB."""
    from idefix_rules.campaign.input.load import load_campaign
    from idefix_rules.campaign.runner import run_campaign
    from idefix_rules.campaign.simulation.run_stage import SilentProgress, SimulationOptions
    from idefix_rules.campaign.storage.dataset_layout import FIRST_ROWS
    from idefix_rules.campaign.storage.store import STATUS_MISSING

    text = TEXT.replace(f"runs: {RUNS}", "runs: 1000000").replace(
        "method: monte_carlo", "method: latin_hypercube")
    text = text[:text.index("  arc:")] + text[text.index("simulation:"):]  # one path
    place_campaign(tmp_path, toy_fmu).write_text(text)
    stopped = uuid.uuid4().hex

    class StopAfterAllocation(SilentProgress):
        def start_path(self, name: str, total: int, done: int, failed: int = 0,
                       up_to: bool = False) -> None:
            raise KeyboardInterrupt(stopped)  # right after the path's runs are allocated

    with pytest.raises(KeyboardInterrupt, match=stopped):
        run_campaign(load_campaign(tmp_path / "campaign.yaml"), SimulationOptions(workers=1),
                     StopAfterAllocation(), report=False)
    results = tmp_path / "out" / "results.h5"
    assert results.stat().st_size < 1_000_000
    with h5py.File(results, "r") as file:
        runs = file["paths/straight/runs"]
        assert runs.attrs["count"] == 1_000_000
        assert runs["status"].shape == (1_000_000,)
        assert np.all(runs["status"][()] == STATUS_MISSING)
        assert runs["signals/x"].shape[0] == FIRST_ROWS
        assert runs["signals/x"].maxshape[0] == 1_000_000
        assert np.all(np.isnan(runs["signals/x"][FIRST_ROWS - 1]))  # fill, never garbage
        parameters = runs["parameters/toy.slip"][()]
        assert np.all(np.isfinite(parameters[:FIRST_ROWS]))
        assert np.all(np.isnan(parameters[FIRST_ROWS:]))  # not allocated yet
        assert file.attrs["state"] == "interrupted"


def test_a_disk_full_when_the_junit_file_is_written(small_disk: Path, toy_fmu: Path,
                                                    tmp_path: Path) -> None:
    """The JUnit file's disk is full (the outputs' is not): exit 3 as every full disk (not
    C207, which is a place the file cannot go), no summary.json giving exit code 1 for a
    command that exited 3, and the command it prints writes both once there is space: it
    gives --junit (without it, it wrote a summary and never the JUnit file)."""
    folder = place_campaign(tmp_path / "campaign", toy_fmu).parent
    reports = small_disk / "reports"
    reports.mkdir()
    junit = reports / "ci.xml"
    filler = fill(small_disk, 0)
    outcome = cli("campaign.yaml", "--quiet", "--no-report", "--runs", "8", "--junit",
                  str(junit), cwd=folder)
    line = assert_one_clear_line(outcome, reports)
    results = (folder / "out" / "results.h5").resolve()
    rewrite = f"idefix-verify evaluate {results} --junit {junit}"
    assert line.endswith(f"more space is needed to write ci.xml; the evaluation is stored in "
                         f"{results}; free space, then write the outputs again with "
                         f"`{rewrite}`"), line
    assert not junit.exists() and not (folder / "out" / "summary.json").exists()
    filler.unlink()
    again = cli(*rewrite.split()[1:], cwd=folder)
    assert again.code == 1, again.stdout + again.stderr
    assert json.loads((folder / "out" / "summary.json").read_text())["exit_code"] == 1
    assert junit.read_text().startswith("<?xml")
