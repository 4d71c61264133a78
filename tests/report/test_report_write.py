"""A report is produced from a small results file: files, content, self-containment, CLI."""

from __future__ import annotations

import re
from pathlib import Path

import h5py
import numpy as np
import pytest
from report_fixture import write_results

from idefix_rules.campaign.storage.store import ResultStore
from idefix_rules.cli import main
from idefix_rules.errors import UserInputError
from idefix_rules.report import prepare_report, write_report
from idefix_rules.report.reading import read_report_data


@pytest.fixture(scope="module")
def written(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """One report of the synthetic results, shared by the read-only tests below."""
    folder = tmp_path_factory.mktemp("report")
    return write_report(write_results(folder / "results.h5"), folder / "out")


def test_report_files_and_header(written: Path) -> None:
    page = written
    assert page == page.parent.parent / "out" / "report.html"
    names = {p.name for p in page.parent.iterdir()}
    assert {"risk_map_all.png", "risk_map_straight.png", "risk_map_detour.png",
            "box_local_error.png", "box_heading_error.png", "dominant_index.png"} <= names
    for png in page.parent.glob("*.png"):
        assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    text = page.read_text(encoding="utf-8")
    assert "report-test 0.1.0" in text
    assert "r" * 64 in text and "c" * 64 in text and "f" * 64 in text
    # Table 1: risk of 'straight' with its CI, the L2 chance, energy and time columns.
    assert "95 % family-wise bounds [%]" in text and "Energy [mAs]" in text and "Time [s]" in text
    assert "not decided at this number of runs" in text
    # A path rejected by the command rules is listed with its reason, without figures.
    assert "too-sharp" in text and "max_turn_angle: command 1 turns 120 deg" in text
    assert "risk_map_too-sharp.png" not in names


def test_report_is_self_contained_and_escaped(written: Path) -> None:
    text = written.read_text(encoding="utf-8")
    # Only the page's own two script elements: its data (JSON) and its code; the verdict
    # reason in the file holds a <script> tag, which shows as text.
    assert text.count("<script") == 2
    assert '<script id="report-data" type="application/json">' in text
    assert "&lt;script&gt;" in text
    assert not re.search(r"(src|href)=\"(?!data:)", text)
    assert "http://" not in text and "https://" not in text
    assert "Content-Security-Policy" in text and "default-src 'none'" in text
    assert text.count('src="data:image/png;base64,') == 6


def test_why_sections_name_worst_runs_and_unexercised_rules(synthetic_results: Path,
                                                            written: Path) -> None:
    store = ResultStore.open(synthetic_results)
    try:
        data = read_report_data(store)
    finally:
        store.close()
    detour = next(p for p in data.paths if p.name == "detour")
    worst = detour.worst_runs()
    assert [run.run for run in worst] == sorted(
        [0, 1, 2], key=lambda j: -detour.i_max[j])  # failed run 3 never listed
    assert set(worst[0].parameters) == {"soil.slip_scale", "initial.y"}
    assert sum(count for _, count in detour.dominance()) == 3
    coverage = {item.name: item for item in data.coverage()}
    assert coverage["collision.L2"].near
    text = written.read_text(encoding="utf-8")
    assert "Worst runs" in text and "soil.slip_scale" in text and "Rule coverage" in text
    # I_roll stays far below its limit: the report says what that means, and no more
    assert not coverage["I_roll"].near
    assert "did not bring near their limits" in text and "<code>I_roll</code>" in text
    assert "would not change these results" not in text


def test_unevaluated_results_still_give_a_report(tmp_path: Path) -> None:
    results = write_results(tmp_path / "plain.h5", evaluated=False)
    text = write_report(results, tmp_path / "out").read_text(encoding="utf-8")
    assert "no path has an evaluation" in text


def test_a_file_that_is_not_a_results_file_is_a_user_error(tmp_path: Path) -> None:
    with h5py.File(tmp_path / "other.h5", "w") as file:
        file.attrs["format"] = "something-else"
    with pytest.raises(UserInputError):
        write_report(tmp_path / "other.h5", tmp_path)
    assert main(["report", str(tmp_path / "missing.h5")]) == 2


def test_cli_writes_next_to_the_results_or_into_out(synthetic_results: Path, tmp_path: Path,
                                                    capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["report", str(synthetic_results), "-o", str(tmp_path / "cli")]) == 0
    assert (tmp_path / "cli" / "report.html").exists()
    assert "report written" in capsys.readouterr().out
    assert main(["report", str(synthetic_results)]) == 0
    assert (synthetic_results.parent / "report.html").exists()


def test_cli_refuses_to_write_into_another_campaigns_folder(
        synthetic_results: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """-o naming a folder with another results file: C714, nothing written there. Its own
    folder (by another spelling, or a link) and a folder with other files are fine."""
    other = tmp_path / "other"
    other.mkdir()
    (other / "results.h5").write_bytes(synthetic_results.read_bytes())
    (other / "summary.json").write_text("{}")
    capsys.readouterr()
    assert main(["report", str(synthetic_results), "-o", str(other)]) == 2
    err = capsys.readouterr().err
    assert "error[C714]" in err and "holds another results file (results.h5)" in err
    assert "Traceback" not in err
    assert sorted(p.name for p in other.iterdir()) == ["results.h5", "summary.json"]
    assert main(["report", str(synthetic_results), "-o",
                 str(synthetic_results.parent / "." )]) == 0
    (tmp_path / "link").symlink_to(synthetic_results.parent)
    assert main(["report", str(synthetic_results), "-o", str(tmp_path / "link")]) == 0
    (tmp_path / "notes").mkdir()
    (tmp_path / "notes" / "summary.json").write_text("{}")
    assert main(["report", str(synthetic_results), "-o", str(tmp_path / "notes")]) == 0


def test_maps_use_the_per_sample_risk_of_the_stored_rulebook(synthetic_results: Path) -> None:
    data, setup, maps = prepare_report(synthetic_results)
    assert maps.per_sample and setup.notes == []
    straight = next(p for p in data.paths if p.name == "straight")
    values = maps.per_path["straight"].values()
    # The fixture's slip grows from 0 at the start to its final value: near the start the
    # per-sample risk is the roll index (0.8 × I_roll, constant in time), far below the runs'
    # I_max (set by the final slip); a map of I_max would show those here.
    xs, _ = maps.grid.centres()
    start = values[(xs < 0.02) & np.isfinite(values)]
    roll = 0.8 * straight.indices["I_roll"]
    assert start.size > 0
    assert start.max() <= roll.max() + 0.01 and start.min() >= roll.min() - 0.01
    # Cell values are means of run maxima: never above the largest I_max, and towards the end
    # (high slip) above anything the roll index alone gives.
    assert roll.max() + 0.05 < np.nanmax(values) <= np.nanmax(straight.i_max) + 1e-12
    assert maps.combined.runs == 7
    # Box plots: final local error of every complete run, finite and non-negative.
    assert straight.final_local_error is not None and straight.final_local_error.size == 4
    assert (straight.final_local_error >= 0).all()


def test_no_two_paths_share_a_figure_file_whatever_their_names() -> None:
    from idefix_rules.report import _safe

    names = ["straight", "arc left", "arc_left", "arc?left", "all", "p" * 100, "p" * 99 + "q",
             "détour", "detour", "Detour", "DETOUR"]
    files = [f"risk_map_{_safe(name)}.png" for name in names]
    # distinct even where the file system ignores case (macOS, Windows)
    assert len({file.lower() for file in files}) == len(files)
    assert "risk_map_all.png" not in files
    assert files[0] == "risk_map_straight.png" and files[2] == "risk_map_arc_left.png"
    assert all(len(file) <= 100 and re.fullmatch(r"[A-Za-z0-9._-]+", file) for file in files)
