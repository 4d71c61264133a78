"""The results diff end to end on a small stored campaign (built-in rover FMU, 4 runs per
path): agreement with the evaluation stage, stored vs recomputed collisions, gates (command
rules, prescreen), exit codes and JSON through the CLI."""

from __future__ import annotations

import json
import os
import re
import shutil
from pathlib import Path

import pytest

from idefix_rules.campaign.evaluation.evaluate import evaluate_store
from idefix_rules.campaign.input.campaign_values import initial_position_sigma, rover_geometry
from idefix_rules.campaign.input.environment import read_terrain
from idefix_rules.campaign.storage.store import ResultStore
from idefix_rules.cli import main
from idefix_rules.diff import load_source
from idefix_rules.diff import results as diff_module
from idefix_rules.diff.results import diff_results
from idefix_rules.results.campaign import rebuilt_campaign
from idefix_rules.results.collisions import collision_function
from idefix_rules.rulebook import compile_rulebook

pytestmark = pytest.mark.slow

FIXTURES = Path(__file__).resolve().parents[1] / "fixtures" / "rulebooks"
VERDICTS = re.compile(r"^verdict .*?(?=^rank by)", re.MULTILINE | re.DOTALL)


def variant(ops_text: str, folder: Path, name: str, verdicts: str | None = None,
            extra: str = "", replace: tuple[tuple[str, str], ...] = ()) -> Path:
    """The frozen operations rulebook with its verdicts replaced and/or text edits, as a file."""
    text = ops_text
    if verdicts is not None:
        text = VERDICTS.sub(verdicts + "\n\n", text)
    for old, new in replace:
        assert old in text
        text = text.replace(old, new)
    path = folder / f"{name}.rules"
    path.write_text(text + extra, encoding="utf-8")
    return path


def evaluated(stored_results: Path) -> list[str]:
    """The paths the stored campaign evaluated (the rover model decides whether a prescreen
    excludes one, e.g. a straight chain whose reference run is held at the rock)."""
    summary = json.loads((stored_results.parent / "summary.json").read_text())
    return [p["name"] for p in summary["paths"] if p["verdict"] not in ("excluded", "rejected")]


def run_json(capsys: pytest.CaptureFixture[str], *args: str) -> tuple[int, dict]:
    capsys.readouterr()
    code = main(["diff", *args, "--format", "json"])
    return code, json.loads(capsys.readouterr().out)


def test_the_same_rulebook_changes_nothing_and_matches_the_stored_evaluation(
        stored_results: Path, campaign_rulebook: Path) -> None:
    ops = load_source(str(campaign_rulebook))
    diff = diff_results([stored_results], ops, ops)
    file = diff.files[0]
    # The campaign was evaluated with this very rulebook: its collisions are reused.
    assert file.collisions == "stored"
    summary = json.loads((stored_results.parent / "summary.json").read_text())
    by_name = {p["name"]: p for p in summary["paths"]}
    for path in file.paths:
        stored = by_name[path.name]
        assert path.old == path.new
        assert path.changed_runs == 0 and not path.top_runs
        assert path.new.verdict == stored["verdict"]
        # summary.json rounds risks to 4 decimals (docs/results-format.md).
        assert path.new.mean_risk == pytest.approx(stored["mean_risk"], abs=5e-5)
        assert path.new.chances == pytest.approx(stored["chances"], abs=5e-5)
        assert path.new.rank == stored["rank"]
    assert list(file.new_ranking) == summary["ranking"]
    assert diff.exit_code() == 0


def test_a_verdict_change_exits_1_and_is_reported_per_path(
        stored_results: Path, ops_text: str, tmp_path: Path,
        capsys: pytest.CaptureFixture[str]) -> None:
    lenient = variant(ops_text, tmp_path, "lenient", "verdict lenient: require risk <= 100 %")
    strict = variant(ops_text, tmp_path, "strict", "verdict strict: require risk < 0 %")
    code, data = run_json(capsys, str(lenient), str(strict), "--results", str(stored_results))
    assert code == 1 and data["exit_code"] == 1
    paths = data["results"]["files"][0]["paths"]
    assert {p["name"] for p in paths} == {"straight", "wide-detour", "smooth-detour", "approach"}
    simulated = evaluated(stored_results)
    assert simulated
    for path in (p for p in paths if p["name"] in simulated):
        assert (path["old"]["verdict"], path["new"]["verdict"]) == ("pass", "fail")
        assert path["verdict_changed"]
        assert path["changed_runs"] == 0  # the indices did not change, only the verdicts
        assert path["old"]["mean_risk"] == path["new"]["mean_risk"]
    changes = {(c["section"], c["name"], c["kind"]) for c in data["rules"]["changes"]}
    assert ("verdict", "lenient", "removed") in changes
    assert ("verdict", "strict", "added") in changes
    # The same change, gated on nothing.
    code, _ = run_json(capsys, str(lenient), str(strict), "--results", str(stored_results),
                       "--fail-on", "never")
    assert code == 0


def test_no_verdict_change_exits_0_even_when_runs_move(
        stored_results: Path, ops_text: str, tmp_path: Path,
        capsys: pytest.CaptureFixture[str]) -> None:
    lenient = variant(ops_text, tmp_path, "lenient", "verdict lenient: require risk <= 100 %")
    heavier = variant(ops_text, tmp_path, "heavier", "verdict lenient: require risk <= 100 %",
                      replace=(("const critical_heading_drift   = 15 deg",
                                "const critical_heading_drift   = 0.01 deg"),))
    code, data = run_json(capsys, str(lenient), str(heavier), "--results", str(stored_results),
                          "--top", "2")
    file = data["results"]["files"][0]
    simulated = evaluated(stored_results)
    assert [p["new"]["verdict"] for p in file["paths"] if p["name"] in simulated] == (
        ["pass"] * len(simulated))
    moved = [p for p in file["paths"] if p["changed_runs"]]
    assert moved, "a 1500x tighter heading limit moves I_max"
    for path in moved:
        assert 0 < len(path["top_runs"]) <= 2
        top = path["top_runs"][0]
        assert top["new_i_max"] > top["old_i_max"]
        assert top["index"] == "I_theta" == top["new_dominant"]
        assert top["delta"] == pytest.approx(top["new_i_max"] - top["old_i_max"])
        deltas = [abs(r["delta"]) for r in path["top_runs"]]
        assert deltas == sorted(deltas, reverse=True)
    rank_changed = any(p["rank_changed"] for p in file["paths"])
    assert code == (1 if file["first_changed"] else 0)
    code_rank, _ = run_json(capsys, str(lenient), str(heavier), "--results",
                            str(stored_results), "--fail-on", "rank")
    assert code_rank == (1 if rank_changed or file["first_changed"] else 0)


def test_other_obstacle_buffers_recompute_collisions_like_the_evaluation_stage(
        stored_results: Path, campaign_rulebook: Path, ops_text: str, tmp_path: Path) -> None:
    wider = variant(ops_text, tmp_path, "wider", replace=(
        ("level L2 below 10 cm buffer 5 cm", "level L2 below 10 cm buffer 7 cm"),))
    ops = load_source(str(campaign_rulebook))
    new = load_source(str(wider))
    diff = diff_results([stored_results], ops, new, chunk_runs=3)
    file = diff.files[0]
    assert file.collisions == "recomputed"
    # What `idefix-verify evaluate --rulebook wider.rules` computes, full rulebook with maps.
    evaluator = compile_rulebook(new.checked)
    store = ResultStore.open(stored_results)
    try:
        campaign = rebuilt_campaign(store)
        collisions = collision_function(campaign.model.environment, evaluator,
                                        read_terrain(stored_results.parent))
        expected = evaluate_store(store, evaluator, rover_geometry(campaign),
                                  initial_position_sigma(campaign), collisions, {}, write=False)
    finally:
        store.close()
    for path in file.paths:
        reference = expected.path(path.name)
        assert path.new.verdict == reference.verdict_text
        assert path.new.mean_risk == pytest.approx(reference.mean_risk, abs=1e-12)
        assert path.new.chances == pytest.approx(reference.chances)
        assert path.new.rank == reference.rank


def test_command_rules_and_prescreens_of_each_side_gate_the_paths(
        stored_results: Path, campaign_rulebook: Path, ops_text: str, tmp_path: Path) -> None:
    ops = load_source(str(campaign_rulebook))
    short = load_source(str(variant(
        ops_text, tmp_path, "short",
        extra='command short_moves: require abs(delta_position) <= 90 cm\n'
              'prescreen never: require risk > 2\n')))
    diff = diff_results([stored_results], ops, short)
    paths = {p.name: p for p in diff.files[0].paths}
    assert paths["straight"].new.verdict == "rejected"
    assert "short_moves" in paths["straight"].new.reasons[0]
    assert paths["wide-detour"].new.verdict == "excluded"
    assert "never" in paths["wide-detour"].new.reasons[0]
    assert all(p.new.rank is None for p in paths.values())
    assert diff.files[0].new_ranking == ()
    assert diff.exit_code() == 1


def test_chunk_size_and_threads_do_not_change_the_result(
        stored_results: Path, ops_text: str, tmp_path: Path,
        monkeypatch: pytest.MonkeyPatch) -> None:
    old = load_source(str(FIXTURES / "idefix-ops-0.9.0.rules"))
    new = load_source(str(variant(ops_text, tmp_path, "same")))
    whole = diff_results([stored_results], old, new, chunk_runs=100, threads=1).to_dict()
    single = diff_results([stored_results], old, new, chunk_runs=1, threads=1).to_dict()
    threaded = diff_results([stored_results], old, new, chunk_runs=1, threads=2).to_dict()
    monkeypatch.setattr(diff_module, "PATHS_AT_ONCE", 1)  # paths scored one after the other
    serial = diff_results([stored_results], old, new, chunk_runs=1, threads=2).to_dict()
    for data in (whole, single, threaded, serial):
        data["files"][0].pop("timings")
    assert whole == single == threaded == serial
    assert len(whole["files"][0]["paths"]) >= 2
    assert any(p["changed_runs"] for p in whole["files"][0]["paths"])


def test_the_text_output_shows_verdicts_risks_and_the_exit_reason(
        stored_results: Path, ops_text: str, tmp_path: Path,
        capsys: pytest.CaptureFixture[str]) -> None:
    lenient = variant(ops_text, tmp_path, "lenient", "verdict lenient: require risk <= 100 %")
    strict = variant(ops_text, tmp_path, "strict", "verdict strict: require risk < 0 %",
                     replace=(("confidence = 95 %", "confidence = 90 %"),))
    copy = tmp_path / "copy" / "results.h5"  # a second campaign's file: the same runs
    copy.parent.mkdir()
    shutil.copyfile(stored_results, copy)
    capsys.readouterr()
    hard = tmp_path / "hard.h5"  # the first again, by a hard link
    os.link(stored_results, hard)
    code = main(["diff", str(lenient), str(strict), "--results", str(stored_results),
                 str(copy), str(stored_results.parent / ".." / stored_results.parent.name /
                                "results.h5"), str(hard)])
    captured = capsys.readouterr()
    out = captured.out
    # the third and fourth are the first by other names: scored once, not counted again
    assert captured.err.count("was given more than once; it is scored once") == 2
    assert code == 1
    # each side's risk bounds at its own rulebook's family-wise confidence
    flat = " ".join(out.split())
    assert re.search(r"[\d.]+–[\d.]+ at 95 %", flat) and re.search(r"[\d.]+–[\d.]+ at 90 %",
                                                                   flat), flat
    assert out.count("results: ") == 2  # two results files, one section each
    assert "pass → fail" in out
    changed = 2 * len(evaluated(stored_results))  # every simulated path, in both files
    assert f"exit code 1: {changed} path verdict(s) changed" in out


def test_the_markdown_changelog_says_what_the_change_does_to_stored_results_and_why_it_exits(
        stored_results: Path, campaign_rulebook: Path, ops_text: str, tmp_path: Path,
        capsys: pytest.CaptureFixture[str]) -> None:
    """`--format md --results` exits 1 only with the reason beside it: the changelog entry
    ends with the effect on the stored campaign and the exit code in words."""
    short = variant(ops_text, tmp_path, "short",
                    extra="command short_moves: require abs(delta_position) <= 90 cm\n")
    capsys.readouterr()
    code = main(["diff", str(campaign_rulebook), str(short), "--results", str(stored_results),
                 "--format", "md"])
    out = capsys.readouterr().out
    assert code == 1
    assert out.index("### Effect on stored campaigns") > out.index("## ")
    assert f"`{stored_results}`" in out
    row = next(line for line in out.splitlines() if line.startswith("| straight |"))
    assert "→ rejected**: " in row and "short_moves" in row
    changed = len(diff_results([stored_results], load_source(str(campaign_rulebook)),
                               load_source(str(short))).verdict_changes())
    assert changed >= 1
    assert f"Exit code 1: {changed} path verdict(s) changed (fail-on verdict)." in out
    assert sum(1 for line in out.splitlines() if line.startswith("| ") and "**" in
               line.split("|")[2]) == changed  # each changed verdict in bold, no other
    # not gated: the changes are said as such, not as "no verdict changes"
    assert main(["diff", str(campaign_rulebook), str(short), "--results", str(stored_results),
                 "--format", "md", "--fail-on", "never"]) == 0
    assert (f"Exit code 0: {changed} path verdict(s) changed, not gated (fail-on never)."
            in capsys.readouterr().out)
    # without a change: exit 0, said as such
    code = main(["diff", str(campaign_rulebook), str(campaign_rulebook), "--results",
                 str(stored_results), "--format", "md"])
    assert code == 0
    assert "Exit code 0: no verdict changes (fail-on verdict)." in capsys.readouterr().out


def test_a_path_without_stored_collisions_has_them_recomputed(
        stored_results: Path, campaign_rulebook: Path, tmp_path: Path) -> None:
    import h5py

    copy = tmp_path / "rock-detour" / "results.h5"
    copy.parent.mkdir()
    shutil.copy(stored_results, copy)  # alone: the terrain the checks need is stored in it
    name = evaluated(stored_results)[0]
    with h5py.File(copy, "r+") as file:
        del file[f"paths/{name}/evaluation/collisions"]
    ops = load_source(str(campaign_rulebook))
    original = diff_results([stored_results], ops, ops).files[0]
    patched = diff_results([copy], ops, ops).files[0]
    assert patched.collisions == f"stored (recomputed for: {name})"
    assert patched.warnings == ()
    assert [p.to_dict() for p in patched.paths] == [p.to_dict() for p in original.paths]


def test_a_path_the_campaign_did_not_simulate_but_a_rulebook_accepts_is_not_simulated(
        stored_results: Path, campaign_rulebook: Path, tmp_path: Path, ops_text: str) -> None:
    import shutil

    import h5py

    copy = tmp_path / "results.h5"
    shutil.copy(stored_results, copy)
    with h5py.File(copy, "r+") as file:
        straight = file["paths/straight"]
        straight.attrs["status"] = "excluded"
        straight.attrs["reason"] = "the reference run fails prescreen 'x'"
        for group in ("runs", "evaluation"):  # absent already if the campaign excluded it
            if group in straight:
                del straight[group]
    ops = load_source(str(campaign_rulebook))
    short = load_source(str(variant(
        ops_text, tmp_path, "short",
        extra="command short_moves: require abs(delta_position) <= 90 cm\n")))
    file = diff_results([copy], ops, short).files[0]
    straight_diff = next(p for p in file.paths if p.name == "straight")
    if "straight" in evaluated(stored_results):
        assert straight_diff.old.verdict == "not simulated"
        assert "run the campaign" in straight_diff.old.reasons[0]
    else:  # the stored reference run itself fails the old rulebook's prescreen
        assert straight_diff.old.verdict == "excluded"
    assert straight_diff.new.verdict == "rejected"
    assert "straight" not in file.old_ranking


def test_shared_evaluation_equals_two_separate_evaluations(stored_results: Path) -> None:
    import numpy as np

    from idefix_rules.campaign.simulation.prescreen import run_context
    from idefix_rules.commands import Command
    from idefix_rules.diff.evaluators import values_only

    old = values_only(load_source(str(FIXTURES / "idefix-ops-0.9.0.rules")).checked)
    new = values_only(load_source(str(FIXTURES / "idefix-ops-1.1.0.rules")).checked)
    store = ResultStore.open(stored_results)
    try:
        campaign = rebuilt_campaign(store)
        chain = tuple(Command(*row) for row in store.path_group("smooth-detour")["chain"][()])
        signals = store.read_runs("smooth-detour", slice(0, 4))
        signals["collision.hits"] = store.path_group(
            "smooth-detour")["evaluation/collisions/hits"][()]
        context = run_context(chain, rover_geometry(campaign), initial_position_sigma(campaign),
                              store.reference("smooth-detour"))
    finally:
        store.close()
    source, shared = old.derived_signals(signals, context), {}
    together = [e.evaluate(signals, context, per_sample=False, source=source, shared=shared)
                for e in (old, new)]
    apart = [e.evaluate(signals, context, per_sample=False) for e in (old, new)]
    assert len(shared) > 5  # index values and chances written alike in both rulebooks
    for joint, alone in zip(together, apart, strict=True):
        for name in alone.index_names:
            np.testing.assert_array_equal(joint.values[name], alone.values[name])
            np.testing.assert_array_equal(joint.raw[name], alone.raw[name])
        for name in alone.chance_names:
            np.testing.assert_array_equal(joint.chances[name], alone.chances[name])
        np.testing.assert_array_equal(joint.i_max, alone.i_max)
        np.testing.assert_array_equal(joint.dominant, alone.dominant)


def test_at_80_columns_path_names_are_whole_and_risk_is_in_percent(
        stored_results: Path, ops_text: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    lenient = variant(ops_text, tmp_path, "lenient", "verdict lenient: require risk <= 100 %")
    strict = variant(ops_text, tmp_path, "strict", "verdict strict: require risk < 0 %")
    monkeypatch.setenv("COLUMNS", "80")
    capsys.readouterr()
    code = main(["diff", str(lenient), str(strict), "--results", str(stored_results)])
    out = capsys.readouterr().out
    assert code == 1
    assert max(len(line) for line in out.splitlines()) <= 80
    for name in ("straight", "wide-detour", "smooth-detour"):  # whole, a block each
        assert re.search(rf"^{re.escape(name)}: pass → fail · rank \d", out, re.M), name
    # risk as `run` shows it: percent with its family-wise bounds, never a bare 0–1 fraction
    assert re.search(r"^  risk \d+\.\d % \(\d+\.\d–\d+\.\d at 95 %\) → \d+\.\d %", out,
                     re.M)
    assert not re.search(r"(?<![\d.])0\.\d{3}(?!\d)", out)


def test_an_area_covering_no_ground_keeps_the_stored_collisions(
        stored_results: Path, campaign_rulebook: Path, tmp_path: Path) -> None:
    # The rulebook the campaign was evaluated with declares a 20 deg steep area; the example's
    # terrain is nowhere near that steep, so the area puts no obstacle on the ground and a
    # rulebook without it keeps the stored collisions. An area starting at 0.5 deg (below the
    # terrain's 2 deg slope) covers the ground with an L3 obstacle: recomputed.
    text = campaign_rulebook.read_text(encoding="utf-8")
    area = "  area highly_inclined steep above critical_inclination level L3 buffer 5 cm"
    assert area in text
    without = tmp_path / "without.rules"
    without.write_text(text.replace(area + " ", "  # ").replace(
        "chance on_steep = any over time (area.highly_inclined.inside > 0)",
        "chance on_steep = any over time (stuck > 2)"), encoding="utf-8")
    ops = load_source(str(campaign_rulebook))
    assert diff_results([stored_results], ops, load_source(str(without))).files[0].collisions \
        == "stored"
    gentle = tmp_path / "gentle.rules"
    gentle.write_text(text.replace("const critical_inclination     = 20 deg",
                                   "const critical_inclination     = 0.5 deg"), encoding="utf-8")
    assert diff_results([stored_results], ops, load_source(str(gentle)),
                        chunk_runs=3).files[0].collisions == "recomputed"
