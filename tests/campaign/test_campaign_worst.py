"""``idefix-verify worst`` on the toy FMU: exit codes and messages, the same outcome for 1 and
2 workers (and on Dask), and searched runs that evaluate and diff read like a campaign's."""

from __future__ import annotations

import json
import shutil
from pathlib import Path
from typing import Any

import campaign_pool_tasks
import h5py
import numpy as np
import pytest
from campaign_texts import RULEBOOK
from diff_warnings import diff_warnings

from idefix_rules.cli import main


def worst(campaign_dir: Path, capsys: pytest.CaptureFixture[str], *extra: str
          ) -> tuple[int, str]:
    code = main(["worst", str(campaign_dir / "campaign.yaml"), "--quiet", "--no-report",
                 *extra])
    captured = capsys.readouterr()
    output = captured.out + captured.err
    assert "Traceback" not in output
    return code, " ".join(output.split())


def searched(campaign_dir: Path, capsys: pytest.CaptureFixture[str]) -> Path:
    """A search of 66 runs into ``campaign_dir``/search, which it must complete (exit 0)."""
    out = campaign_dir / "search"
    code, output = worst(campaign_dir, capsys, "--runs", "66", "--out", str(out))
    assert code == 0, output
    return out


def comparable(record: dict[str, Any]) -> dict[str, Any]:
    """worst.json without what names the folder it was written to."""
    return {key: value for key, value in record.items() if key not in ("results", "campaign")}


def stored_runs(results: Path) -> dict[str, Any]:
    found: dict[str, Any] = {}
    with h5py.File(results, "r") as file:
        for name, group in file["paths"].items():
            if "runs" not in group:
                continue
            found[name] = {
                "status": group["runs/status"][()].tolist(),
                "parameters": {key: np.nan_to_num(data[()], nan=-1.0).tolist()
                               for key, data in group["runs/parameters"].items()},
                "x": np.nan_to_num(group["runs/signals/x"][()], nan=-1.0).tolist(),
                "i_max": np.nan_to_num(group["evaluation/i_max"][()], nan=-1.0).tolist()}
    return found


def test_the_outcome_is_the_same_for_one_and_two_workers(
        campaign_dir: Path, capsys: pytest.CaptureFixture[str]) -> None:
    outcomes = []
    for workers in ("1", "2"):
        out = campaign_dir / f"out-{workers}"
        code, output = worst(campaign_dir, capsys, "--runs", "70", "--workers", workers,
                             "--out", str(out))
        assert code == 0, output
        record = json.loads((out / "worst.json").read_text())
        outcomes.append((comparable(record), stored_runs(out / "results.h5")))
    assert outcomes[0] == outcomes[1]
    record, runs = outcomes[0]
    searched = {path["name"]: path for path in record["paths"]}
    # the too-fast chain breaks a command rule: not searched, and said so
    assert searched["too-fast"]["status"] == "rejected"
    for name in ("straight", "arc"):
        path = searched[name]
        # 70 runs: 30 kept for the boundary's three rays, 40 to search (24 + 12 + 4)
        assert path["status"] == "searched" and path["search_runs"] == 40
        assert path["runs_used"] <= 70
        assert path["worst"]["risk"] >= path["nominal"]["risk"]
        status = runs[name]["status"]
        # rows the search did not use are marked not needed, as an adaptive campaign does
        assert status[:path["runs_used"]] == [1] * path["runs_used"]
        assert set(status[path["runs_used"]:]) <= {3}
        # the stored parameters are the worlds searched: the worst one's included
        row = path["worst"]["run"]
        if row is not None:
            for key, entry in path["worst"]["parameters"].items():
                assert runs[name]["parameters"][key][row] == pytest.approx(entry["value"],
                                                                           rel=1e-5)
            assert runs[name]["i_max"][row] == pytest.approx(path["worst"]["risk"], abs=1e-4)


def test_another_seed_searches_other_worlds(campaign_dir: Path,
                                            capsys: pytest.CaptureFixture[str]) -> None:
    first = worst(campaign_dir, capsys, "--runs", "66", "--out", str(campaign_dir / "a"))
    second = worst(campaign_dir, capsys, "--runs", "66", "--seed", "6", "--out",
                   str(campaign_dir / "b"))
    assert first[0] == second[0] == 0
    a = stored_runs(campaign_dir / "a" / "results.h5")["straight"]["parameters"]
    b = stored_runs(campaign_dir / "b" / "results.h5")["straight"]["parameters"]
    assert a["toy.slip"][:5] != b["toy.slip"][:5]


def test_the_searched_runs_are_evaluated_again_and_diffed_like_a_campaign(
        campaign_dir: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = searched(campaign_dir, capsys)
    results = out / "results.h5"
    stricter = campaign_dir / "stricter.rules"
    stricter.write_text(RULEBOOK.replace("limit  = critical_slip", "limit  = 20 %")
                        .replace('version "0.1.0"', 'version "0.2.0"'))
    code = main(["evaluate", str(results), "--rulebook", str(stricter)])
    evaluated = capsys.readouterr()
    # with I_s limited to 20 % both searched chains fail acceptable_risk (and too-fast is
    # rejected by its command rule): exit 1
    assert code == 1 and "Traceback" not in evaluated.out + evaluated.err
    assert "holds a worst-case search" in " ".join((evaluated.out + evaluated.err).split())
    code = main(["diff", str(campaign_dir / "test.rules"), str(stricter), "--results",
                 str(results)])
    diffed = capsys.readouterr()
    # arc's verdict changes, pass (not decided) -> fail: diff exits 1 (default --fail-on verdict)
    assert code == 1 and "Traceback" not in diffed.out + diffed.err
    assert "I_s" in diffed.out


def test_nothing_uncertain_is_exit_2_at_the_uncertainty_section(
        campaign_dir: Path, capsys: pytest.CaptureFixture[str]) -> None:
    text = (campaign_dir / "campaign.yaml").read_text()
    start = text.index("  parameters:\n")
    end = text.index("paths:")
    fixed = text[:start] + "  parameters:\n    toy.slip: {distribution: fixed, value: 0.1}\n" \
        + text[end:]
    (campaign_dir / "campaign.yaml").write_text(fixed)
    code, output = worst(campaign_dir, capsys)
    assert code == 2
    assert "campaign.yaml:" in output and "error[C710]" in output
    assert "no parameter that varies" in output
    assert not (campaign_dir / "out").exists()


def test_a_budget_too_small_says_how_many_runs_it_needs(
        campaign_dir: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code, output = worst(campaign_dir, capsys, "--runs", "40")
    assert code == 2 and "error[C711]" in output
    assert "at least 66 runs per path" in output and "--runs 66" in output


def test_a_critical_level_above_every_weight_is_exit_2(
        campaign_dir: Path, capsys: pytest.CaptureFixture[str]) -> None:
    rules = campaign_dir / "test.rules"
    rules.write_text(rules.read_text().replace("weight = 1", "weight = 0.8"))
    code, output = worst(campaign_dir, capsys, "--runs", "66")
    assert code == 2 and "error[C712]" in output and "--critical 0.8" in output
    code, output = worst(campaign_dir, capsys, "--runs", "66", "--critical", "80 %")
    assert code == 0, output


@pytest.mark.parametrize(("option", "value", "message"), [
    ("--critical", "0", "a run risk lies in (0, 1]"),
    ("--critical", "150 %", "a run risk lies in (0, 1] (0 % … 100 %), got 150 %"),
    # `--critical 90 %` unquoted reaches the command as 90: said how to write it
    ("--critical", "90", "got 90; for 90 %, write it as one argument: --critical 90% or "
                         "--critical \"90 %\""),
    ("--critical", "100", "got 100; for 100 %, write it as one argument"),
    ("--critical", "101", "a run risk lies in (0, 1] (0 % … 100 %), got 101"),
    ("--critical", "high", "expected a run risk such as 1, 0.9 or 90 %"),
    ("--tail", "0.7", "a tail probability lies in (0, 0.5)"),
    ("--runs", "0", "expected a positive whole number"),
    ("--axes", "-1", "expected a whole number >= 0"),
    ("--seed", "-3", "a seed is a whole number from 0 to 2^64 - 1"),
])
def test_usage_mistakes_are_exit_2_with_what_was_expected(
        campaign_dir: Path, capsys: pytest.CaptureFixture[str], option: str, value: str,
        message: str) -> None:
    code, output = worst(campaign_dir, capsys, option, value)
    assert code == 2 and message in output


def test_a_missing_campaign_is_exit_2(tmp_path: Path,
                                      capsys: pytest.CaptureFixture[str]) -> None:
    code = main(["worst", str(tmp_path / "nowhere.yaml"), "--quiet"])
    output = " ".join((capsys.readouterr().err).split())
    assert code == 2 and "error[C010]" in output and "Traceback" not in output


@pytest.mark.slow
def test_dask_searches_the_same_worlds_as_the_local_pool(
        campaign_dir: Path, capsys: pytest.CaptureFixture[str]) -> None:
    local = worst(campaign_dir, capsys, "--runs", "66", "--out", str(campaign_dir / "local"))
    dask = worst(campaign_dir, capsys, "--runs", "66", "--out", str(campaign_dir / "dask"),
                 "--dask-local", "--workers", "2")
    assert local[0] == dask[0] == 0, dask[1]
    records = [json.loads((campaign_dir / name / "worst.json").read_text())
               for name in ("local", "dask")]
    assert comparable(records[0]) == comparable(records[1])


def test_every_round_runs_on_one_pool_of_workers(
        campaign_dir: Path, capsys: pytest.CaptureFixture[str],
        monkeypatch: pytest.MonkeyPatch) -> None:
    # The workers (and the FMU each loaded) live from the first round to the last: one pool
    # for the reference runs, one for every generation and boundary round, not one per round.
    made, maps = campaign_pool_tasks.count_pools(monkeypatch)
    code, output = worst(campaign_dir, capsys, "--runs", "66", "--workers", "2", "--out",
                         str(campaign_dir / "pooled"))
    assert code == 0, output
    assert len(maps) >= 4  # the references, then at least three rounds
    # the references' pool (kept from the FMU's set-up to the reference runs), then one for
    # every round
    assert made == [True, True]


def test_the_report_opens_with_the_worst_case_and_draws_the_worst_runs(
        campaign_dir: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = campaign_dir / "reported"
    code = main(["worst", str(campaign_dir / "campaign.yaml"), "--quiet", "--runs", "66",
                 "--out", str(out)])
    output = capsys.readouterr().out
    assert code == 0 and f"report: {out / 'report.html'}" in " ".join(output.split())
    page = (out / "report.html").read_text()
    assert 'id="worst"' in page and 'id="decision"' not in page
    assert "holds a worst-case search" in page
    record = json.loads((out / "worst.json").read_text())
    for path in record["paths"]:
        assert f"<td>{path['name']}</td>" in page
    assert (out / "risk_map_straight.png").is_file()


def test_a_search_into_a_campaigns_folder_is_refused_and_leaves_its_results(
        campaign_dir: Path, capsys: pytest.CaptureFixture[str]) -> None:
    # too-fast breaks the command rule wheel_rate_limit (0.5 rad/s): rejected, exit 1
    assert main([str(campaign_dir / "campaign.yaml"), "--quiet", "--no-report"]) == 1
    capsys.readouterr()
    results = campaign_dir / "out" / "results.h5"
    before = results.stat().st_mtime_ns
    code, output = worst(campaign_dir, capsys, "--runs", "66", "--out",
                         str(campaign_dir / "out"))
    assert code == 2 and "error[C713]" in output and "holds a campaign's results" in output
    # the hint names the folder the search writes into without --out, not one in --out's
    other = campaign_dir / "other"
    other.mkdir()
    shutil.copy(results, other / "results.h5")
    code, output = worst(campaign_dir, capsys, "--runs", "66", "--out", str(other))
    default = (campaign_dir / "out" / "worst").resolve()
    assert code == 2 and f"leave out --out (the search writes into {default})" in " ".join(
        output.split()), output
    assert results.stat().st_mtime_ns == before
    assert not (campaign_dir / "out" / "results.previous.h5").exists()
    # the default folder is inside the campaign's: it leaves the campaign's results alone
    code, output = worst(campaign_dir, capsys, "--runs", "66")
    assert code == 0, output
    assert results.stat().st_mtime_ns == before
    assert (campaign_dir / "out" / "worst" / "worst.json").is_file()


def test_an_interrupted_search_is_run_again_never_resumed_and_a_campaign_sets_it_aside(
        campaign_dir: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A search cannot be resumed: what evaluate says of an interrupted one is the command
    that runs it again, and a campaign run into its folder neither offers to resume it nor
    leaves its worst.json beside the campaign's results."""
    import h5py

    out = searched(campaign_dir, capsys)
    with h5py.File(out / "results.h5", "r+") as file:
        file.attrs["state"] = "interrupted"
        runs, seed = int(file.attrs["runs"]), int(file.attrs["seed"])
    assert main(["evaluate", str(out / "results.h5")]) == 1
    captured = capsys.readouterr()
    said = " ".join((captured.out + captured.err).split())
    assert "holds a worst-case search that is interrupted" in said
    # with the search's shape: a command without it searched otherwise (--critical 1, the
    # default tail, 2 axes, 3 rounds here)
    assert (f"a search cannot be resumed: run it again with `idefix-verify worst "
            f"{campaign_dir / 'campaign.yaml'} --out {out} --runs {runs} --seed {seed} "
            "--critical 1 --tail 0.0001 --axes 2 --rounds 3`") in said, said
    assert "--resume" not in said
    # interrupted before it stored its outcome or an evaluation: the report says to run it
    # again (a campaign's would say to continue it with --resume)
    unevaluated = campaign_dir / "unevaluated"
    shutil.copytree(out, unevaluated)
    with h5py.File(unevaluated / "results.h5", "r+") as file:
        for name in list(file["paths"]):
            if "evaluation" in file["paths"][name]:
                del file["paths"][name]["evaluation"]
        del file["evaluation"]
        del file["worst"]
    assert main(["report", str(unevaluated / "results.h5")]) == 0
    page = " ".join((unevaluated / "report.html").read_text().split())
    assert ("none yet: the worst-case search is interrupted and its runs so far were never "
            "evaluated; a search cannot be resumed: run `idefix-verify worst` again") in page
    assert "--resume" not in page
    capsys.readouterr()
    # a campaign into the search's folder: the search and its record go aside, said once
    code = main([str(campaign_dir / "campaign.yaml"), "--quiet", "--no-report", "--out",
                 str(out)])
    assert code == 1  # too-fast is rejected
    said = " ".join(capsys.readouterr().out.split())
    assert (f"note: {out / 'results.h5'} held a worst-case search (idefix-verify worst): it "
            "is kept as results.previous.h5, its worst.json as worst.previous.json") in said
    assert "--resume" not in said and "another campaign" not in said
    assert not (out / "worst.json").exists() and (out / "worst.previous.json").is_file()


def test_the_report_of_a_search_scored_again_under_another_rulebook_says_whose_findings(
        campaign_dir: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """The worst worlds and boundaries are the search's rulebook's; scored since under
    another, the report says so and gives each worst run's I_max under it."""
    import h5py

    out = searched(campaign_dir, capsys)
    rules = campaign_dir / "test.rules"
    lenient = campaign_dir / "lenient.rules"
    lenient.write_text(rules.read_text().replace('version "0.1.0"', 'version "0.2.0"')
                       .replace("limit  = 1\n", "limit  = 4\n", 1))
    assert main(["report", str(out / "results.h5")]) == 0
    page = " ".join((out / "report.html").read_text().split())
    assert "Searched under another rulebook" not in page and "(now " not in page
    assert main(["evaluate", str(out / "results.h5"), "--rulebook", str(lenient)]) == 1
    assert main(["report", str(out / "results.h5")]) == 0
    page = " ".join((out / "report.html").read_text().split())
    assert ("<b>Searched under another rulebook.</b> The search found these worlds under "
            "rulebook campaign-test 0.1.0; its runs were scored since under campaign-test "
            "0.2.0") in page
    record = json.loads((out / "worst.json").read_text())
    shown = 0
    with h5py.File(out / "results.h5") as file:
        for path in record["paths"]:
            run = (path.get("worst") or {}).get("run")
            if path.get("status") != "searched" or run is None:
                continue
            now = float(file["paths"][path["name"]]["evaluation"]["i_max"][run])
            assert f"{100 * path['worst']['risk']:.1f} % (now {100 * now:.1f} %)" in page
            shown += 1
    assert shown >= 1


def test_a_search_decides_no_chain_to_send_in_evaluate_and_its_summary(
        campaign_dir: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Its verdicts are over chosen worlds: 'run more to settle it' or 'send' would mislead."""
    out = searched(campaign_dir, capsys)
    import h5py

    with h5py.File(out / "results.h5") as file:
        stored = json.loads(file["evaluation"].attrs["summary"])
    assert stored["decision"]["text"].startswith("none from a worst-case search: its runs are "
                                                 "the worlds the search chose")
    assert main(["evaluate", str(out / "results.h5")]) == 1  # too-fast is rejected
    said = " ".join(capsys.readouterr().out.split())
    assert "Decision: none from a worst-case search" in said
    assert "run more" not in said.split("Decision:")[1]


def test_the_searched_runs_are_judged_with_the_campaigns_waivers(
        campaign_dir: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A waived failure is no failure for the stored evaluation of a search either (and raises
    no other chain's confidence level: campaign/statistics/budget.py)."""
    campaign = campaign_dir / "campaign.yaml"
    campaign.write_text(campaign.read_text() + """waivers:
  - rule: acceptable_risk
    path: all
    reason: "a test of the searched runs' evaluation"
    approved_by: "ops"
    until: 2099-01-01
""")
    out = searched(campaign_dir, capsys)
    with h5py.File(out / "results.h5", "r") as file:
        summary = json.loads(file["evaluation"].attrs["summary"])
    waived = {path["name"]: [w["rule"] for w in path.get("waivers", [])]
              for path in summary["paths"]}
    assert any("acceptable_risk" in rules for rules in waived.values()), waived


def test_a_search_is_unpaired_and_its_evaluation_checks_no_expectation(
        campaign_dir: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Each path searches its own worlds: run j of two paths is not the same world, so the file
    says unpaired, nothing compares paths world by world, and evaluate checks no `expect:`
    (worst-case.md), also on a file whose `paired` claims otherwise (an earlier version's)."""
    campaign = campaign_dir / "campaign.yaml"
    campaign.write_text(campaign.read_text() + "expect:\n  - {path: straight, verdict: pass}\n")
    out = searched(campaign_dir, capsys)
    results = out / "results.h5"
    with h5py.File(results, "r") as file:
        assert not file.attrs["paired"]
        summary = json.loads(file["evaluation"].attrs["summary"])
    assert summary["paired"] is False and summary["pairs"] == []
    assert main(["report", str(results)]) == 0
    capsys.readouterr()
    assert "Paired comparisons" not in (out / "report.html").read_text()
    with h5py.File(results, "r+") as file:
        file.attrs["paired"] = True  # as the search stored it before
    code = main(["evaluate", str(results)])
    captured = capsys.readouterr()
    output = " ".join((captured.out + captured.err).split())
    summary = json.loads((out / "summary.json").read_text())
    # straight fails over the searched worlds: exit 1 from the verdicts, not the expectation
    assert code == 1 and "Traceback" not in output
    assert "same worlds" not in output and "expect straight" not in output
    assert ("the campaign's expect: entries are not checked (a search states facts about "
            "worlds, not about how often they occur): the exit code follows the verdicts"
            ) in output
    assert "CI verdicts (no expectations: every path must pass)" in output
    assert summary["expectations"] == [] and summary["pairs"] == []
    assert summary["paired"] is False


def test_diff_of_a_search_warns_as_evaluate_does(
        campaign_dir: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = searched(campaign_dir, capsys)
    results = out / "results.h5"
    said = (f"{results} holds a worst-case search (idefix-verify worst): its runs are the "
            "worlds the search chose, not draws of the campaign's distributions")
    words, warnings = diff_warnings(campaign_dir / "test.rules", results, capsys)
    assert f"warning: {said}" in words
    assert any(warning.startswith(said) for warning in warnings), warnings


def test_a_stale_lock_a_search_takes_over_is_a_note_as_for_a_run(
        campaign_dir: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A run says a lock it took over as a note; the search said it as a warning."""
    import socket
    import subprocess
    import sys

    from idefix_rules.campaign.storage.ownership import LOCK_FILE, Owner, process_start

    folder = campaign_dir / "out" / "worst"
    folder.mkdir(parents=True)
    gone = subprocess.Popen([sys.executable, "-c", "pass"])
    gone.wait()
    (folder / LOCK_FILE).write_text(Owner(gone.pid, socket.gethostname(),
                                          "2025-05-01T12:00:03+02:00", "idefix-verify worst c",
                                          process_start(gone.pid)).to_json())
    code, output = worst(campaign_dir, capsys, "--runs", "66")
    assert code == 0, output
    assert f"note: {folder / LOCK_FILE}: took over the lock of pid {gone.pid}" in output, output
    assert "warning: " + str(folder / LOCK_FILE) not in output
