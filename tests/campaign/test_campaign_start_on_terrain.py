"""A rover whose nominal start lies off the terrain it is given is refused before anything is
simulated (C216, at the line that sets the start): off the grid the rover model drives on the
edge heights carried on, a terrain no one gave it."""

from __future__ import annotations

from pathlib import Path

import pytest

from idefix_rules.campaign.input.environment import build_terrain
from idefix_rules.campaign.input.load import load_campaign
from idefix_rules.campaign.input.terrain_checks import check_start_on_terrain
from idefix_rules.cli import main
from idefix_rules.errors import UserInputError

ROOT = Path(__file__).parents[2]
START = 'initial.x: {distribution: normal, mean: "0 m", std: "1 cm"}'


def _campaign(tmp_path: Path, mean: str) -> Path:
    text = (ROOT / "campaigns" / "flat-control.yaml").read_text()
    text = text.replace("../rulebooks/", f"{ROOT / 'rulebooks'}/")
    assert START in text
    text = text.replace(START, START.replace('"0 m"', f'"{mean}"'))
    path = tmp_path / f"c{len(list(tmp_path.iterdir()))}.yaml"
    path.write_text(text)
    return path


def test_the_start_may_lie_on_the_terrain_edge_and_not_beyond(tmp_path: Path) -> None:
    campaign = load_campaign(_campaign(tmp_path, "0 m"))
    extent = build_terrain(campaign.model.environment, campaign.dem).extent
    x_max = extent[1]
    check_start_on_terrain(load_campaign(_campaign(tmp_path, f"{x_max!r} m")), extent)
    beyond = load_campaign(_campaign(tmp_path, f"{x_max + 1e-6!r} m"))
    with pytest.raises(UserInputError) as refused:
        check_start_on_terrain(beyond, extent)
    (diagnostic,) = refused.value.diagnostics
    assert diagnostic.code == "C216" and "outside the terrain" in diagnostic.message
    assert diagnostic.span is not None and diagnostic.span.line == \
        beyond.text[:beyond.text.index("initial.x:")].count("\n") + 1


def test_a_start_far_off_the_terrain_is_exit_2_before_any_run(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = _campaign(tmp_path, "50 m")
    code = main(["run", str(path), "--runs", "2", "--quiet", "--no-report",
                 "--out", str(tmp_path / "out")])
    captured = capsys.readouterr()
    output = captured.out + captured.err
    assert code == 2, output
    assert "error[C216]: the rover starts at (50 m, 0 m), outside the terrain" in output
    assert not (tmp_path / "out" / "results.h5").exists()


def test_the_error_points_at_the_coordinate_that_is_off(tmp_path: Path) -> None:
    """A start off the terrain in y only: C216 at initial.y's line, not initial.x's."""
    text = _campaign(tmp_path, "0 m").read_text()
    start_y = 'initial.y: {distribution: normal, mean: "0 m", std: "1 cm"}'
    assert start_y in text
    path = tmp_path / "off-in-y.yaml"
    path.write_text(text.replace(start_y, start_y.replace('"0 m"', '"50 m"')))
    campaign = load_campaign(path)
    extent = build_terrain(campaign.model.environment, campaign.dem).extent
    with pytest.raises(UserInputError) as refused:
        check_start_on_terrain(campaign, extent)
    (diagnostic,) = refused.value.diagnostics
    assert diagnostic.message.startswith("the rover starts at (0 m, 50 m)")
    assert diagnostic.span is not None and diagnostic.span.line == \
        campaign.text[:campaign.text.index("initial.y:")].count("\n") + 1
