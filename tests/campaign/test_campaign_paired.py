"""Paired campaigns: run ``j`` of every path simulates the same drawn world (common random
numbers) unless ``uncertainty: {paired: false}``; a path's draws never depend on which other
paths the campaign has, nor on the worker count; ``results.h5`` says which it was."""

from __future__ import annotations

from pathlib import Path

import h5py
import numpy as np
import pytest
from campaign_texts import CAMPAIGN
from test_campaign_robustness import assert_same_datasets, copy_campaign

from idefix_rules.campaign.input.load import load_campaign
from idefix_rules.campaign.runner import run_campaign
from idefix_rules.campaign.simulation.run_stage import SimulationOptions
from idefix_rules.cli import main

UNPAIRED = CAMPAIGN.replace("  method: monte_carlo\n", "  method: monte_carlo\n  paired: false\n")
LATIN = CAMPAIGN.replace("method: monte_carlo", "method: latin_hypercube")
# The campaign without its first path: the others must draw what they drew with it.
WITHOUT_STRAIGHT = CAMPAIGN.replace(
    '  straight:\n    - {max_wheel_rate: "0.1 rad/s", delta_position: "0.1 m", '
    'delta_heading: "0 deg"}\n', "")


def parameters(results: Path) -> dict[str, dict[str, np.ndarray]]:
    """Each simulated path's sampled parameters per run."""
    with h5py.File(results, "r") as file:
        return {name: {key: file["paths"][name]["runs/parameters"][key][()]
                       for key in file["paths"][name]["runs/parameters"]}
                for name in file["paths"] if "runs" in file["paths"][name]}


def simulate(folder: Path, source: Path, text: str, workers: int = 1) -> Path:
    path = copy_campaign(source, folder, text)
    campaign = load_campaign(path).with_overrides(workers=workers)
    run_campaign(campaign, SimulationOptions(workers=workers), report=False)
    return folder / "out" / "results.h5"


def test_the_campaign_file_validates_paired(campaign_dir: Path,
                                            capsys: pytest.CaptureFixture[str]) -> None:
    path = campaign_dir / "campaign.yaml"
    path.write_text(CAMPAIGN.replace("  method: monte_carlo\n",
                                     "  method: monte_carlo\n  paired: sometimes\n"))
    assert main([str(path), "--quiet", "--no-report"]) == 2
    assert "paired" in capsys.readouterr().err


@pytest.mark.parametrize("text", [CAMPAIGN, LATIN], ids=["monte_carlo", "latin_hypercube"])
def test_run_j_of_every_path_draws_the_same_world_by_default(campaign_dir: Path, tmp_path: Path,
                                                             text: str) -> None:
    results = simulate(tmp_path / "paired", campaign_dir, text)
    drawn = parameters(results)
    assert sorted(drawn) == ["arc", "straight"]  # too-fast breaks a command rule
    for key in drawn["straight"]:
        assert np.array_equal(drawn["straight"][key], drawn["arc"][key]), key
    with h5py.File(results, "r") as file:
        assert bool(file.attrs["paired"]) is True
        assert "spawn_key=(*s, j)" in file.attrs["seed_derivation"]


def test_an_unpaired_campaign_draws_each_path_its_own(campaign_dir: Path,
                                                      tmp_path: Path) -> None:
    results = simulate(tmp_path / "unpaired", campaign_dir, UNPAIRED)
    drawn = parameters(results)
    for key in ("initial.x", "initial.y", "toy.slip"):
        assert not np.any(drawn["straight"][key] == drawn["arc"][key]), key
    with h5py.File(results, "r") as file:
        assert bool(file.attrs["paired"]) is False


@pytest.mark.parametrize("paired", [True, False], ids=["paired", "unpaired"])
def test_a_path_draws_the_same_without_the_others(campaign_dir: Path, tmp_path: Path,
                                                  paired: bool) -> None:
    text = CAMPAIGN if paired else UNPAIRED
    alone = WITHOUT_STRAIGHT if paired else WITHOUT_STRAIGHT.replace(
        "  method: monte_carlo\n", "  method: monte_carlo\n  paired: false\n")
    with_all = parameters(simulate(tmp_path / "all", campaign_dir, text))
    without = parameters(simulate(tmp_path / "without", campaign_dir, alone))
    assert list(without) == ["arc"]
    for key, values in with_all["arc"].items():
        assert np.array_equal(values, without["arc"][key]), key


def test_a_paired_campaign_is_the_same_on_one_and_two_workers(campaign_dir: Path,
                                                              tmp_path: Path) -> None:
    one = simulate(tmp_path / "one", campaign_dir, LATIN, workers=1)
    two = simulate(tmp_path / "two", campaign_dir, LATIN, workers=2)
    assert_same_datasets(one, two)


def test_resume_refuses_results_drawn_the_other_way(campaign_dir: Path, tmp_path: Path,
                                                    capsys: pytest.CaptureFixture[str]) -> None:
    results = simulate(tmp_path / "first", campaign_dir, CAMPAIGN)
    with h5py.File(results, "a") as file:
        del file.attrs["paired"]  # as a file written before campaigns were paired
    path = tmp_path / "first" / "campaign.yaml"
    assert main([str(path), "--quiet", "--no-report", "--resume"]) == 2
    assert "its paired is False, this campaign's is True" in capsys.readouterr().err


# twin drives arc's chain: both pass, so the decision depends on their comparison
TWINS = CAMPAIGN.replace("runs: 6", "runs: auto\nmax_runs: 200\nmin_runs: 10\nbatch_runs: 16") \
    .replace("paths:\n", 'paths:\n  twin:\n    - {max_wheel_rate: "0.1 rad/s", '
             'delta_position: "0.1 m", delta_heading: "20 deg"}\n'
             '    - {max_wheel_rate: "0.1 rad/s", delta_position: "0.05 m", '
             'delta_heading: "-20 deg"}\n')
MARGIN_RULEBOOK = "\ncombine {\n  indifference = 5 %\n}\n"


def run_twins(folder: Path, source: Path, text: str, margin: bool,
              capsys: pytest.CaptureFixture[str]) -> tuple[dict, str]:
    import json

    path = copy_campaign(source, folder, text)
    if margin:
        rules = folder / "test.rules"
        rules.write_text(rules.read_text() + MARGIN_RULEBOOK)
    capsys.readouterr()
    main([str(path), "--no-report"])
    return json.loads((folder / "out" / "summary.json").read_text()), capsys.readouterr().out


def test_an_adaptive_campaign_stops_on_a_tie_and_reports_it(
        campaign_dir: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    # twin and arc drive the same chain: in the same worlds their run risks are equal
    summary, out = run_twins(tmp_path / "tie", campaign_dir, TWINS, True, capsys)
    paths = {p["name"]: p for p in summary["paths"]}
    used = paths["twin"]["runs_used"]
    assert used < 200 and paths["arc"]["runs_used"] == used
    assert paths["twin"]["stop_reason"].startswith(f"decided after {used} runs")
    assert paths["twin"]["rank"] == paths["arc"]["rank"]
    assert summary["paired"] is True and summary["indifference"] == pytest.approx(0.05)
    assert summary["ties"] == [["arc", "twin"]]  # equal risks: in name order
    [pair] = [p for p in summary["pairs"] if set(p["paths"]) == {"twin", "arc"}]
    assert pair["outcome"] == "tied" and pair["equal"] == pair["shared_runs"] == used
    assert pair["first_safer"] == pair["second_safer"] == 0 and pair["needed"]
    assert -0.05 < pair["ci"][0] <= 0.0 <= pair["ci"][1] < 0.05
    assert "Ranking: arc > twin > straight\ntie: arc = twin (risk difference within ±5 %)" \
        in out
    # straight fails: no decision depends on its rank, it stops on its verdict alone
    assert paths["straight"]["stop_reason"].endswith("(no decision depends on its rank)")


@pytest.mark.parametrize(("text", "margin"), [
    (TWINS, False),
    (TWINS.replace("  method: monte_carlo\n", "  method: monte_carlo\n  paired: false\n"), True)],
    ids=["no margin", "unpaired"])
def test_without_a_margin_or_without_pairing_equal_paths_never_tie(
        campaign_dir: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str], text: str,
        margin: bool) -> None:
    summary, out = run_twins(tmp_path / "open", campaign_dir, text, margin, capsys)
    assert summary["ties"] == [] and "tie:" not in out
    paths = {p["name"]: p for p in summary["paths"]}
    assert paths["twin"]["rank"] != paths["arc"]["rank"]


def test_the_ranking_s_neighbours_are_compared_in_words_in_the_console_junit_and_report(
        campaign_dir: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    # One line per neighbour pair of the ranking: in how many of the same worlds the higher-
    # ranked path was the safer, the risk difference and its interval, what that decides.
    import json
    import re
    import xml.etree.ElementTree as ET

    folder = tmp_path / "words"
    path = copy_campaign(campaign_dir, folder, TWINS)
    rules = folder / "test.rules"
    rules.write_text(rules.read_text() + MARGIN_RULEBOOK)
    capsys.readouterr()
    main([str(path), "--junit", str(folder / "junit.xml")])
    out = capsys.readouterr().out
    summary = json.loads((folder / "out" / "summary.json").read_text())
    tie = next(p for p in summary["pairs"] if p["paths"] == ["arc", "twin"])
    last = next(p for p in summary["pairs"] if p["paths"] == ["twin", "straight"])
    assert tie["outcome"] == "tied" and tie["needed"]
    assert last["outcome"] == "open" and not last["needed"]  # straight fails: stopped early
    first = (f"arc and twin are tied (risk difference within ±5 %): arc safer in 0 % of the "
             f"same worlds (0 of {tie['shared_runs']}): risk +0.0 % (")
    shared, safer = last["shared_runs"], last["first_safer"]
    second = (f"twin vs straight not compared further (no decision depends on their order): "
              f"twin safer in {100 * safer / shared:.0f} % of the same worlds ({safer} of "
              f"{shared}): risk ")
    flat = " ".join(out.split())  # the console wraps long lines
    found = re.search(r"Ranking: arc > twin > straight tie: arc = twin \(risk difference "
                      rf"within ±5 %\) {re.escape(first)}([\d.]+) % CI (\S+) % … (\S+) %\) "
                      rf"{re.escape(second)}(\S+) % \(([\d.]+) % CI (\S+) % … (\S+) %\)",
                      flat)
    assert found, flat
    # summary.json keeps 4 significant digits: the printed numbers agree to its last digit
    printed = [float(found.group(k)) / 100 for k in range(1, 8)]
    stored = [tie["confidence"], *tie["ci"], last["risk_difference"], last["confidence"],
              *last["ci"]]
    assert printed == pytest.approx(stored, abs=0.0011)
    assert "arc vs straight" not in flat and "arc is safer than straight" not in flat
    first = first[:-2]  # up to the numbers

    suite = ET.parse(folder / "junit.xml").getroot().find("testsuite")
    assert suite is not None
    neighbours = suite.findtext("system-out", "").splitlines()
    assert neighbours[0].startswith(f"pair: {first}") and len(neighbours) == 2
    assert neighbours[1].startswith(f"pair: {second}")
    cases = {case.get("name"): case.findtext("system-out", "") for case in suite.iter("testcase")}
    assert f"pair: {first}" in cases["arc"]
    assert "pair: arc vs straight not compared further" in cases["arc"]  # all its pairs
    assert "pair: straight vs arc not compared further" in cases["straight"]
    assert "pair:" not in cases["too-fast"]  # rejected: never simulated, never compared

    report = (folder / "out" / "report.html").read_text()
    assert '<h3 id="pairs">Paired comparisons</h3>' in report
    assert first in report
    assert "<td data-label=\"Outcome\">tied (within ±5 %)</td>" in report
    assert "not compared further (no decision depends on it)</td>" in report
