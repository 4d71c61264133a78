"""Every planned run's drawn start must lie on the terrain, as the nominal start must (C216):
off it the rover model would drive on the grid's edge heights carried on. Checked on the
draws themselves, before anything is simulated."""

from __future__ import annotations

from pathlib import Path

import pytest

from idefix_rules.campaign.input.environment import build_terrain
from idefix_rules.campaign.input.load import load_campaign
from idefix_rules.campaign.input.sampling import planned_draws
from idefix_rules.campaign.input.terrain_checks import check_drawn_starts_on_terrain
from idefix_rules.cli import main
from idefix_rules.errors import UserInputError

ROOT = Path(__file__).parents[2]
START_X = '    initial.x: {distribution: normal, mean: "0 m", std: "1 cm"}\n'


def _campaign(tmp_path: Path, start_x: str) -> Path:
    text = (ROOT / "campaigns" / "flat-control.yaml").read_text()
    assert START_X in text
    text = text.replace("../rulebooks/", f"{ROOT / 'rulebooks'}/").replace(
        "output: ../results/flat-control", f"output: {tmp_path / 'out'}")
    text = text.replace(START_X, f"    initial.x: {start_x}\n")
    path = tmp_path / f"c{len(list(tmp_path.iterdir()))}.yaml"
    path.write_text(text)
    return path


def _refused(path: Path) -> str | None:
    campaign = load_campaign(path)
    extent = build_terrain(campaign.model.environment, campaign.dem).extent
    try:
        check_drawn_starts_on_terrain(campaign, extent)
    except UserInputError as failure:
        return failure.diagnostics[0].message
    return None


@pytest.mark.parametrize(("start_x", "refused"), [
    ('{distribution: uniform, low: "-1.99 m", high: "1.99 m"}', False),  # inside, x ±2 m
    ('{distribution: uniform, low: "-2.5 m", high: "1.5 m"}', True),  # an eighth beyond
    ('{distribution: normal, mean: "0 m", std: "2 m"}', True),
])
def test_a_drawn_start_off_the_terrain_is_c216_naming_the_run(
        tmp_path: Path, start_x: str, refused: bool) -> None:
    message = _refused(_campaign(tmp_path, start_x))
    assert (message is not None) is refused
    if message is not None:
        assert "of path straight starts at (" in message and "outside the terrain" in message


def test_the_run_named_draws_the_start_said(tmp_path: Path) -> None:
    path = _campaign(tmp_path, '{distribution: normal, mean: "0 m", std: "2 m"}')
    message = _refused(path)
    assert message is not None
    run = int(message.split("run ")[1].split(" ")[0])
    planned, draws = planned_draws(load_campaign(path), ["straight"])
    assert planned == 64
    assert f"starts at ({draws['straight']['initial.x'][run]:g} m" in message


def test_the_cli_says_it_before_simulating(tmp_path: Path,
                                           capsys: pytest.CaptureFixture[str]) -> None:
    path = _campaign(tmp_path, '{distribution: normal, mean: "0 m", std: "2 m"}')
    assert main([str(path), "--runs", "8", "--quiet", "--no-report"]) == 2
    output = "".join(capsys.readouterr())
    assert "error[C216]" in output and "Traceback" not in output
    assert not (tmp_path / "out" / "results.h5").exists()


def test_the_distribution_pointed_at_is_the_coordinate_that_leaves(tmp_path: Path) -> None:
    path = _campaign(tmp_path, '{distribution: normal, mean: "0 m", std: "1 cm"}')
    text = path.read_text().replace(
        '    initial.y: {distribution: normal, mean: "0 m", std: "1 cm"}',
        '    initial.y: {distribution: normal, mean: "0 m", std: "2 m"}')
    path.write_text(text)
    campaign = load_campaign(path)
    extent = build_terrain(campaign.model.environment, campaign.dem).extent
    with pytest.raises(UserInputError) as caught:
        check_drawn_starts_on_terrain(campaign, extent)
    line = caught.value.diagnostics[0].span.line
    assert "initial.y" in text.splitlines()[line - 1]


def test_a_worst_case_search_draws_its_own_worlds_and_is_not_refused_for_planned_ones(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    from idefix_rules.campaign import preparation

    path = _campaign(tmp_path, '{distribution: normal, mean: "0 m", std: "2 m"}')
    campaign = load_campaign(path)
    with pytest.raises(UserInputError):  # a campaign's planned runs: refused
        preparation.prepare_simulation(campaign, lambda said: None, "again")
    prepared = preparation.prepare_simulation(campaign, lambda said: None, "again",
                                              planned_runs=False)
    assert prepared.terrain is not None


@pytest.mark.parametrize(("xs", "refused"), [
    (("10 m", "11 m"), True),     # entirely beyond x = 2 m: another frame
    (("1.9 m", "2.5 m"), False),  # across the edge: fine
])
def test_a_keep_out_polygon_entirely_off_the_terrain_is_c206(
        tmp_path: Path, xs: tuple[str, str], refused: bool) -> None:
    from idefix_rules.campaign.input.terrain_checks import check_polygons_on_terrain

    path = _campaign(tmp_path, '{distribution: normal, mean: "0 m", std: "1 cm"}')
    low, high = xs
    path.write_text(path.read_text().replace(
        "  regolith:\n",
        f'  keep_out:\n    - {{name: crater, level: L3, polygon: [["{low}", "1 m"], '
        f'["{high}", "1 m"], ["{high}", "1.5 m"]]}}\n  regolith:\n', 1))
    campaign = load_campaign(path)
    extent = build_terrain(campaign.model.environment, campaign.dem).extent
    if not refused:
        check_polygons_on_terrain(campaign, extent)
        return
    with pytest.raises(UserInputError) as caught:
        check_polygons_on_terrain(campaign, extent)
    found = caught.value.diagnostics[0]
    assert found.code == "C206" and "keep_out[0] (crater) lies entirely outside" in found.message
