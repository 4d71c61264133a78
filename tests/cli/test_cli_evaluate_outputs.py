"""What `evaluate` leaves beside the results it evaluates again: the outputs that spoke for the
evaluation it replaces are set aside once the new one is written (beside the results too
when `--out` names another folder), never when it is refused; a symbolic link is followed to
the file it names; a Ctrl-C says what state the files are in and how to evaluate again."""

from __future__ import annotations

import json
import os
from pathlib import Path

import h5py
import pytest
from test_cli_user_errors import campaign, materialise

from idefix_rules.cli import main

SPOKE = ("summary.json", "report.html")  # what a run writes beside its results.h5


def _stored(folder: Path, toy: Path, append: str = "") -> Path:
    """A campaign run with its report: ``out/results.h5``, ``summary.json``, report and
    figures."""
    folder.mkdir(exist_ok=True)
    materialise(folder, campaign(append=append), toy)
    here = Path.cwd()
    try:
        os.chdir(folder)
        assert main(["campaign.yaml", "--runs", "4", "--quiet"]) in (0, 1)
    finally:
        os.chdir(here)
    out = folder / "out"
    assert all((out / name).is_file() for name in SPOKE)
    return out / "results.h5"


def _words(capsys: pytest.CaptureFixture[str]) -> str:
    captured = capsys.readouterr()
    output = captured.out + captured.err
    assert "Traceback" not in output
    return " ".join(output.split())


def _evaluated_with(results: Path) -> str:
    with h5py.File(results, "r") as file:
        return str(json.loads(file["evaluation"].attrs["summary"])["rulebook"]["path"])


def test_evaluate_into_another_folder_sets_aside_what_spoke_beside_the_results(
        tmp_path: Path, cli_toy_fmu: Path, capsys: pytest.CaptureFixture[str]) -> None:
    results = _stored(tmp_path, cli_toy_fmu)
    out = results.parent
    other = tmp_path / "rescored"
    assert main(["evaluate", str(results), "--rulebook", str(tmp_path / "test.rules"),
                 "--out", str(other)]) == 1, _words(capsys)
    assert (other / "summary.json").is_file()
    for name in SPOKE:  # they spoke for the evaluation results.h5 no longer holds
        assert not (out / name).exists(), name
    assert (out / "summary.previous.json").is_file() and (out / "report.previous.html").is_file()
    assert not [path.name for path in out.glob("*.png") if ".previous." not in path.name]


@pytest.mark.parametrize("mistake", ["missing", "syntax", "waiver"])
def test_a_refused_evaluation_sets_nothing_aside(
        mistake: str, tmp_path: Path, cli_toy_fmu: Path,
        capsys: pytest.CaptureFixture[str]) -> None:
    results = _stored(tmp_path, cli_toy_fmu)
    out = results.parent
    argv = ["evaluate", str(results)]
    if mistake == "missing":
        argv += ["--rulebook", str(tmp_path / "missing.rules")]
        said = "error[E002]"
    elif mistake == "syntax":
        broken = tmp_path / "broken.rules"
        broken.write_text((tmp_path / "test.rules").read_text() + "verdict oops: require\n")
        argv += ["--rulebook", str(broken)]
        said = "broken.rules:"
    else:  # the stored campaign's waiver names a rule this rulebook does not have
        renamed = tmp_path / "renamed.rules"
        renamed.write_text((tmp_path / "test.rules").read_text().replace(
            "acceptable_risk", "risk_kept"))
        with h5py.File(results, "r+") as file:
            text = file["provenance/campaign"][()].decode()
            del file["provenance/campaign"]
            file["provenance/campaign"] = text + (
                "waivers:\n  - {rule: acceptable_risk, path: arc, reason: \"known\", "
                "approved_by: \"J. Doe\", until: 2099-12-31}\n")
        argv += ["--rulebook", str(renamed)]
        said = "error[C211]"
    before = sorted(path.name for path in out.iterdir())
    assert main(argv) == 2
    assert said in _words(capsys)
    assert sorted(path.name for path in out.iterdir()) == before


@pytest.mark.parametrize("when", ["scoring", "summary"])
def test_an_interrupted_evaluation_says_what_state_the_files_are_in(
        when: str, tmp_path: Path, cli_toy_fmu: Path, capsys: pytest.CaptureFixture[str],
        monkeypatch: pytest.MonkeyPatch) -> None:
    from idefix_rules.campaign import rescore
    from idefix_rules.campaign.outcome import outputs

    results = _stored(tmp_path, cli_toy_fmu)
    out = results.parent
    before = _evaluated_with(results)

    def interrupted(*args: object, **kwargs: object) -> None:
        raise KeyboardInterrupt

    if when == "scoring":
        monkeypatch.setattr(rescore, "evaluate_store", interrupted)
    else:
        monkeypatch.setattr(outputs, "write_summary", interrupted)
    stricter = tmp_path / "stricter.rules"
    stricter.write_text((tmp_path / "test.rules").read_text().replace("50 %", "40 %"))
    assert main(["evaluate", str(results), "--rulebook", str(stricter)]) == 130
    words = _words(capsys)
    again = f"evaluate again with `idefix-verify evaluate {results} --rulebook {stricter}`"
    if when == "scoring":
        assert _evaluated_with(results) == before
        assert (f"interrupted: {results} is unchanged (it holds the evaluation it had); the "
                "outputs that spoke for that evaluation are set aside (summary.previous.json, "
                "report.previous.html and ") in words, words
    else:
        assert _evaluated_with(results) == str(stricter.resolve())
        assert (f"interrupted: the new evaluation is stored in {results}; "
                f"{out / 'summary.json'} is not written") in words, words
    assert again in words
    assert not (out / "summary.json").exists() and (out / "summary.previous.json").is_file()
    assert not list(out.glob(".idefix.lock"))  # the lock went with the command


def test_evaluate_through_a_symbolic_link_rewrites_the_file_it_names(
        tmp_path: Path, cli_toy_fmu: Path, capsys: pytest.CaptureFixture[str]) -> None:
    results = _stored(tmp_path, cli_toy_fmu)
    latest = tmp_path / "latest"
    latest.mkdir()
    link = latest / "results.h5"
    link.symlink_to(os.path.relpath(results, latest))
    stricter = tmp_path / "stricter.rules"
    stricter.write_text((tmp_path / "test.rules").read_text().replace("50 %", "40 %"))
    assert main(["evaluate", str(link), "--rulebook", str(stricter)]) == 1
    _words(capsys)
    assert link.is_symlink() and link.resolve() == results.resolve()
    assert _evaluated_with(results) == str(stricter.resolve())
    # the outputs go where the file is, and the ones that spoke for it there are set aside
    assert sorted(path.name for path in latest.iterdir()) == ["results.h5"]
    summary = json.loads((results.parent / "summary.json").read_text())
    assert summary["results"] == str(results.resolve())
    assert (results.parent / "report.previous.html").is_file()
