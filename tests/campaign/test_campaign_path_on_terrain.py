"""A chain that, driven as commanded from the nominal start, takes a wheel of the built-in rover
off the terrain it is given is refused before anything is simulated (C218, at the path, naming
the command and the point): beyond the grid the rover model drives on the edge heights carried
on, a terrain no one gave it."""

from __future__ import annotations

from pathlib import Path

import pytest

from idefix_rules.campaign.input.environment import build_terrain
from idefix_rules.campaign.input.load import load_campaign
from idefix_rules.campaign.input.terrain_checks import check_paths_on_terrain
from idefix_rules.cli import main
from idefix_rules.errors import UserInputError

ROOT = Path(__file__).parents[2]
START = 'initial.x: {distribution: normal, mean: "0 m", std: "1 cm"}'
# the flat-control terrain is 4 m a side, centred: x from -2 to 2 m
HALF_WHEELBASE = 0.20


def _campaign(tmp_path: Path, start_x: float, paths: str | None = None) -> Path:
    text = (ROOT / "campaigns" / "flat-control.yaml").read_text()
    text = text.replace("../rulebooks/", f"{ROOT / 'rulebooks'}/")
    assert START in text
    text = text.replace(START, START.replace('"0 m"', f'"{start_x!r} m"'))
    if paths is not None:
        text = text[:text.index("paths:")] + paths
    path = tmp_path / f"c{len(list(tmp_path.iterdir()))}.yaml"
    path.write_text(text)
    return path


STRAIGHT = """paths:
  ahead:
    - {max_wheel_rate: "0.05 rad/s", delta_position: "0.5 m", delta_heading: "0 deg"}
    - {max_wheel_rate: "0.05 rad/s", delta_position: "0.5 m", delta_heading: "0 deg"}
"""


def test_a_drive_whose_front_wheels_end_on_the_edge_passes_and_a_millimetre_beyond_is_c218(
        tmp_path: Path) -> None:
    on_edge = 2.0 - 1.0 - HALF_WHEELBASE  # the front wheels end at x = 2 m
    inside = load_campaign(_campaign(tmp_path, on_edge - 1e-3, STRAIGHT))
    extent = build_terrain(inside.model.environment, inside.dem).extent
    assert extent[1] == pytest.approx(2.0)
    check_paths_on_terrain(inside, extent)
    beyond = load_campaign(_campaign(tmp_path, on_edge + 1e-3, STRAIGHT))
    with pytest.raises(UserInputError) as refused:
        check_paths_on_terrain(beyond, extent)
    (diagnostic,) = refused.value.diagnostics
    assert diagnostic.code == "C218"
    # the wheels leave during the second command, at the edge
    assert "paths.ahead:" in diagnostic.message and "during command 2" in diagnostic.message
    assert "at (2.001 m, 0.26 m)" in diagnostic.message  # the front right wheel, beyond
    assert diagnostic.span is not None and diagnostic.span.line == \
        beyond.text[:beyond.text.index("  ahead:")].count("\n") + 1


def test_a_turn_on_the_spot_near_the_edge_swings_the_wheels_off(tmp_path: Path) -> None:
    """A point turn moves no centre but sweeps the wheels: the corner at the wheelbase and track
    reaches sqrt(0.2² + 0.26²) = 0.328 m from the centre, beyond the 0.2 m the wheels stand ahead
    before the turn."""
    turn = """paths:
  spin:
    - {max_wheel_rate: "0.05 rad/s", delta_position: "0 m", delta_heading: "90 deg"}
"""
    reach = (HALF_WHEELBASE ** 2 + 0.26 ** 2) ** 0.5
    inside = load_campaign(_campaign(tmp_path, 2.0 - reach - 1e-3, turn))
    extent = build_terrain(inside.model.environment, inside.dem).extent
    check_paths_on_terrain(inside, extent)
    # standing 0.25 m from the edge the wheels start on it and leave while turning
    beyond = load_campaign(_campaign(tmp_path, 2.0 - 0.25, turn))
    with pytest.raises(UserInputError) as refused:
        check_paths_on_terrain(beyond, extent)
    assert "during command 1" in refused.value.diagnostics[0].message


def test_every_campaign_shipped_keeps_its_chains_on_its_terrain() -> None:
    for path in sorted((ROOT / "campaigns").glob("*.yaml")):
        campaign = load_campaign(path)
        check_paths_on_terrain(campaign,
                               build_terrain(campaign.model.environment, campaign.dem).extent)


def test_a_chain_off_the_terrain_is_exit_2_before_any_run(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = _campaign(tmp_path, 1.5)  # the three flat-control chains drive 1 m ahead
    code = main(["run", str(path), "--runs", "2", "--quiet", "--no-report",
                 "--out", str(tmp_path / "out")])
    captured = capsys.readouterr()
    output = captured.out + captured.err
    assert code == 2, output
    assert "error[C218]: paths.straight: driven as commanded from the nominal start" in output
    assert "error[C218]: paths.wide-detour:" in output
    assert not (tmp_path / "out" / "results.h5").exists()


def test_a_rock_and_the_start_off_the_terrain_are_said_at_once(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = _campaign(tmp_path, 2.5)
    text = path.read_text().replace(
        "  terrain:\n", '  rocks:\n    - {x: "5 m", y: "0 m", radius: "4 cm", level: L2}\n'
                        "  terrain:\n", 1)
    path.write_text(text)
    code = main(["run", str(path), "--runs", "2", "--quiet", "--no-report",
                 "--out", str(tmp_path / "out")])
    captured = capsys.readouterr()
    output = captured.out + captured.err
    assert code == 2, output
    assert "error[C206]" in output and "error[C216]" in output
    assert "error[C218]" not in output  # from a start off the terrain every chain is off


def test_a_fast_turn_after_a_slow_short_command_is_sampled_too(tmp_path: Path) -> None:
    """Each command is sampled on its own: a 0.01 m step at a crawl (about 1000 s) before a
    full turn on the spot (327 s) left the turn between two samples of the whole chain."""
    chain = """paths:
  crawl-then-spin:
    - {max_wheel_rate: "0.00001 rad/s", delta_position: "0.01 m", delta_heading: "0 deg"}
    - {max_wheel_rate: "0.05 rad/s", delta_position: "0 m", delta_heading: "360 deg"}
"""
    campaign = load_campaign(_campaign(tmp_path, 1.75, chain))
    with pytest.raises(UserInputError) as refused:
        check_paths_on_terrain(campaign, build_terrain(campaign.model.environment,
                                                       campaign.dem).extent)
    assert "during command 2" in refused.value.diagnostics[0].message


def test_wheels_off_the_terrain_before_any_command_are_said_so(tmp_path: Path) -> None:
    """The start (the body centre) is on the terrain, a wheel is not: C218 says it is off at
    the start, not during the first command."""
    reverse = """paths:
  back:
    - {max_wheel_rate: "0.05 rad/s", delta_position: "-0.5 m", delta_heading: "0 deg"}
"""
    campaign = load_campaign(_campaign(tmp_path, 1.9, reverse))
    with pytest.raises(UserInputError) as refused:
        check_paths_on_terrain(campaign, build_terrain(campaign.model.environment,
                                                       campaign.dem).extent)
    message = refused.value.diagnostics[0].message
    assert "at the start, before any command, at (2.1 m, " in message, message
