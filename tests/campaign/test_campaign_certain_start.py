"""A rulebook that reads the tolerance radius needs an uncertain start position: the radius
starts at the start position's σ, so with a certain start it is 0 until a chain turns and every
run of a chain that does not turn is critical for no reason of its own. Such a campaign is
refused before anything is simulated (C219, at `uncertainty`), with the other mistakes of the
campaign said at once."""

from __future__ import annotations

from pathlib import Path

import pytest

from idefix_rules.campaign.input.load import load_campaign
from idefix_rules.campaign.input.validate import check_tolerance_start
from idefix_rules.campaign.preparation import compile_rulebook_file
from idefix_rules.cli import main
from idefix_rules.errors import UserInputError

ROOT = Path(__file__).parents[2]
START = ('    initial.x: {distribution: normal, mean: "0 m", std: "1 cm"}\n'
         '    initial.y: {distribution: normal, mean: "0 m", std: "1 cm"}\n')
SOIL = '    soil.cohesion: {distribution: log_normal, median: "250 Pa", sigma: 0.4}\n'


def _campaign(tmp_path: Path, start: str, rulebook: str = "idefix-ops.rules",
              extra: str = "") -> Path:
    text = (ROOT / "campaigns" / "flat-control.yaml").read_text()
    assert START in text
    text = text.replace(START, start + SOIL).replace(
        "../rulebooks/idefix-ops.rules", str(ROOT / "rulebooks" / rulebook))
    text = text.replace("output: ../results/flat-control", f"output: {tmp_path / 'out'}")
    path = tmp_path / f"c{len(list(tmp_path.iterdir()))}.yaml"
    path.write_text(text + extra)
    return path


def _problems(path: Path, rulebook: Path | None = None) -> list[str]:
    campaign = load_campaign(path)
    evaluator = compile_rulebook_file(rulebook or campaign.rulebook)
    try:
        check_tolerance_start(campaign, evaluator)
    except UserInputError as failure:
        return [f"{d.code}@{d.span.line}" for d in failure.diagnostics]
    return []


@pytest.mark.parametrize(("start", "refused"), [
    ("", True),                                                            # not given
    ('    initial.x: {distribution: fixed, value: "0 m"}\n', True),         # fixed
    ('    initial.x: {distribution: normal, mean: "0 m", std: "1 um"}\n', False),  # just above 0
    ('    initial.y: {distribution: uniform, low: "-1 mm", high: "1 mm"}\n', False),
])
def test_a_certain_start_is_refused_and_any_spread_is_not(
        tmp_path: Path, start: str, refused: bool) -> None:
    found = _problems(_campaign(tmp_path, start))
    assert bool(found) is refused
    if refused:
        text = _campaign(tmp_path, start).read_text().splitlines()
        line = int(found[0].split("@")[1])
        assert found[0].startswith("C219@") and ("uncertainty:" in text[line - 1]
                                                 or "initial.x" in text[line - 1])


def test_a_rulebook_that_does_not_read_the_tolerance_radius_needs_no_spread(
        tmp_path: Path) -> None:
    rulebook = tmp_path / "no-position.rules"
    rulebook.write_text("""rulebook "no-position" version "1.0.0"
purpose "slip only"
index I_s "slip" {
  value  = max over time (max over wheels (abs(wheel.slip)))
  limit  = 70 %
  weight = 1
}
verdict acceptable_risk: require risk <= 70 %
""")
    assert _problems(_campaign(tmp_path, ""), rulebook) == []


def test_the_cli_refuses_it_with_every_other_mistake_and_simulates_nothing(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    waiver = ("waivers:\n  - {rule: acceptable_risk, path: straight, reason: \"x\", "
              "approved_by: \"me\", until: 2020-01-01}\n")
    path = _campaign(tmp_path, "", extra=waiver)
    text = path.read_text().replace('      size: "4 m"', '      size: "1 m"')  # chains leave
    path.write_text(text)
    assert main([str(path), "--runs", "2", "--quiet", "--no-report"]) == 2
    output = " ".join("".join(capsys.readouterr()).split())
    assert "Traceback" not in output
    assert "error[C219]: rulebook idefix-ops reads the tolerance radius" in output
    assert "error[C213]" in output and "error[C218]" in output  # said together
    assert not (tmp_path / "out" / "results.h5").exists()



def test_chains_that_all_turn_need_no_spread_and_one_that_does_not_is_named(
        tmp_path: Path) -> None:
    """The radius grows by tolerance_growth per radian turned: a chain that turns ends with a
    radius above 0 and a finite index; only the chains that never turn are refused."""
    path = _campaign(tmp_path, "")
    text = path.read_text()
    turning = text[:text.index("  straight:")] + text[text.index("  wide-detour:"):]
    turning = turning.replace("  - {path: straight, max_mean_risk: \"30 %\"}\n",
                              "  - {path: wide-detour, verdict: fail}\n")
    path.write_text(turning)
    assert _problems(path) == []
    campaign = load_campaign(_campaign(tmp_path, ""))
    evaluator = compile_rulebook_file(campaign.rulebook)
    with pytest.raises(UserInputError) as caught:
        check_tolerance_start(campaign, evaluator)
    message = caught.value.diagnostics[0].message
    assert "with chains that do not turn (straight) the radius stays 0" in message
