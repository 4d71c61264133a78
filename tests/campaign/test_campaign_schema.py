"""Campaign files: valid ones load in SI, broken ones give precise file:line:col messages."""

from __future__ import annotations

import math
import textwrap
from pathlib import Path

import pytest

from idefix_rules.campaign.input.load import load_campaign
from idefix_rules.errors import UserInputError

GOOD = """\
name: demo
rulebook: demo.rules
runs: 8
output: out
paths:
  straight:
    - {max_wheel_rate: "0.05 rad/s", delta_position: "1 m", delta_heading: "0 deg"}
  detour:
    - {max_wheel_rate: "3 deg/s", delta_position: "50 cm", delta_heading: "30 deg"}
    - {max_wheel_rate: "0.05 rad/s", delta_position: "0.5 m", delta_heading: "-30 deg"}
uncertainty:
  method: latin_hypercube
  seed: 3
  parameters:
    initial.x: {distribution: normal, mean: "0 m", std: "1 cm"}
    soil.cohesion: {distribution: log_normal, median: "250 Pa", sigma: 0.3}
environment:
  terrain:
    synthetic: {slope: "2 deg", roughness: "2 mm", seed: 4}
  rocks:
    - {x: "0.5 m", y: "-0.26 m", radius: "5 cm", level: L2}
expect:
  - {path: detour, verdict: pass}
  - {rank_first: detour}
  - {path: straight, max_collision_chance: {L2: "95 %"}}
"""


def write(tmp_path: Path, text: str, name: str = "campaign.yaml") -> Path:
    (tmp_path / "demo.rules").write_text("rulebook \"demo\" version \"1.0.0\"\n")
    path = tmp_path / name
    path.write_text(textwrap.dedent(text))
    return path


def messages(path: Path) -> list[str]:
    with pytest.raises(UserInputError) as caught:
        load_campaign(path)
    return [f"{d.span.line}:{d.span.column}: {d.message}" for d in caught.value.diagnostics]


def test_a_valid_campaign_loads_in_si_with_paths_resolved(tmp_path: Path) -> None:
    campaign = load_campaign(write(tmp_path, GOOD))
    assert [p.name for p in campaign.paths] == ["straight", "detour"]
    detour = campaign.paths[1].chain
    assert math.isclose(detour[0].max_wheel_rate, math.radians(3))
    assert math.isclose(detour[0].delta_position, 0.5)
    assert math.isclose(detour[1].delta_heading, -math.pi / 6)
    assert campaign.rulebook == (tmp_path / "demo.rules").resolve()
    assert campaign.output == (tmp_path / "out").resolve()
    assert campaign.runs == 8 and campaign.seed == 3
    assert campaign.model.environment.rocks[0].axes == (0.05, 0.05, 0.05)
    overridden = campaign.with_overrides(runs=2, seed=9)
    assert (overridden.runs, overridden.seed) == (2, 9)


def test_relative_paths_resolve_against_the_campaign_file_not_the_cwd(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    sub = tmp_path / "sub"
    sub.mkdir()
    path = write(sub, GOOD)
    monkeypatch.chdir(tmp_path)
    assert load_campaign(Path("sub") / path.name).rulebook == (sub / "demo.rules").resolve()


# Each broken file with the messages it must produce (line:column: message).
CATALOGUE = [
    ("bare number for an angle",
     GOOD.replace('delta_heading: "30 deg"', 'delta_heading: "90"'),
     ['9:75: paths.detour[0].delta_heading: expected an angle, got "90"']),
    ("bare number for a rate",
     GOOD.replace('max_wheel_rate: "3 deg/s"', "max_wheel_rate: 0.05"),
     ["9:24: paths.detour[0].max_wheel_rate: expected an angular rate, got 0.05"]),
    ("wrong dimension",
     GOOD.replace('delta_position: "50 cm"', 'delta_position: "50 deg"'),
     ['9:51: paths.detour[0].delta_position: expected a length, got "50 deg" (an angle)']),
    ("unknown unit",
     GOOD.replace('delta_position: "1 m"', 'delta_position: "1 parsec"'),
     ["7:54: paths.straight[0].delta_position: unknown unit 'parsec'"]),
    ("unknown key",
     GOOD.replace("runs: 8", "runz: 8"),
     ["3:1: runz: unknown key"]),
    ("missing rulebook",
     GOOD.replace("rulebook: demo.rules\n", ""),
     ["1:1: rulebook: missing required key"]),
    ("unknown distribution",
     GOOD.replace("distribution: normal", "distribution: gaussian"),
     ["15:31: uncertainty.parameters.initial.x: unknown distribution 'gaussian' (expected one "
      "of: 'fixed', 'normal', 'truncated_normal', 'uniform', 'log_normal')"]),
    ("missing distribution field",
     GOOD.replace(', std: "1 cm"', ""),
     ["15:16: uncertainty.parameters.initial.x.std: missing required key"]),
    ("mixed dimensions in a distribution",
     GOOD.replace('std: "1 cm"', 'std: "1 deg"'),
     ["15:16: uncertainty.parameters.initial.x: values disagree in dimension: mean is a length, "
      "std is an angle"]),
    ("unknown sampling method",
     GOOD.replace("method: latin_hypercube", "method: halton"),
     ["12:11: uncertainty.method: expected 'monte_carlo', 'latin_hypercube' or 'sobol', got "
      "'halton'"]),
    ("runs not positive",
     GOOD.replace("runs: 8", "runs: 0"),
     ["3:7: runs: expected a whole number of runs from 1 to 1000000 or 'auto', got 0"]),
    ("runs neither a count nor auto",
     GOOD.replace("runs: 8", "runs: often"),
     ["3:7: runs: expected a whole number of runs from 1 to 1000000 or 'auto', got \"often\""]),
    ("rock with two sizes",
     GOOD.replace('radius: "5 cm"', 'radius: "5 cm", semi_axes: ["1 cm", "1 cm", "1 cm"]'),
     ["21:7: environment.rocks[0]: give exactly one of 'radius' or 'semi_axes'"]),
    ("bad expectation",
     GOOD.replace("{rank_first: detour}", "{first: detour}"),
     ["24:5: expect[1]: an expectation needs one of: verdict, rank_first, max_mean_risk, "
      "max_collision_chance", "24:6: expect[1].first: unknown key"]),
    ("expectation names an unknown path",
     GOOD.replace("{rank_first: detour}", "{rank_first: detuor}"),
     ["24:18: expect[1].rank_first: unknown path 'detuor' (paths: straight, detour)"]),
    ("rulebook file missing",
     GOOD.replace("rulebook: demo.rules", "rulebook: nowhere.rules"),
     ["2:11: rulebook: rulebook 'nowhere.rules' not found (relative paths start at the "
      "campaign file's folder)"]),
    ("empty chain",
     GOOD.replace(
         '  straight:\n    - {max_wheel_rate: "0.05 rad/s", delta_position: "1 m", '
         'delta_heading: "0 deg"}\n', "  straight: []\n"),
     ["6:13: paths.straight: expected at least 1 value, got 0"]),
    ("YAML syntax",
     GOOD.replace("runs: 8", "runs: [8"),
     ["4:7: invalid YAML: expected ',' or ']', but got ':'"]),
    ("duplicate key",
     GOOD.replace("runs: 8", "runs: 8\nruns: 9"),
     ["4:1: duplicate key 'runs'"]),
    ("not a mapping", "- just\n- a list\n",
     ["1:1: a campaign file is a mapping (key: value lines)"]),
    ("expectation of two kinds",
     GOOD.replace("  - {path: detour, verdict: pass}",
                  "  - {path: detour, verdict: pass, max_mean_risk: \"30 %\"}"),
     ["23:5: expect[0]: an expectation has one kind; this one gives verdict and max_mean_risk: "
      "write each as its own entry of expect"]),
]


@pytest.mark.parametrize(("what", "text", "expected"), CATALOGUE, ids=[c[0] for c in CATALOGUE])
def test_broken_campaign_files_give_precise_messages(tmp_path: Path, what: str, text: str,
                                                     expected: list[str]) -> None:
    assert messages(write(tmp_path, text)) == expected


def test_every_error_of_a_file_is_reported_at_once(tmp_path: Path) -> None:
    text = GOOD.replace("runs: 8", "runs: -1").replace('"30 deg"', '"30"')
    found = messages(write(tmp_path, text))
    assert len(found) == 2
    assert found[0].startswith("3:7: runs:")
    assert "delta_heading: expected an angle" in found[1]


def test_the_cli_renders_the_message_with_the_source_line_and_exit_code_2(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from idefix_rules.cli import main

    path = write(tmp_path, GOOD.replace('delta_heading: "30 deg"', 'delta_heading: "90"'))
    assert main([str(path)]) == 2
    err = capsys.readouterr().err
    assert f'{path}:9:75: error[C100]: paths.detour[0].delta_heading: expected an angle, ' \
           'got "90"' in err
    assert "Traceback" not in err


def test_a_missing_campaign_file_is_a_user_error(tmp_path: Path) -> None:
    with pytest.raises(UserInputError, match="not found"):
        load_campaign(tmp_path / "absent.yaml")


@pytest.mark.parametrize(("old", "new", "expected"), [
    ("seed: 3", f"seed: {2**64}", f"13:9: uncertainty.seed: a seed is a whole number from 0 to "
                                  f"2^64 - 1 ({2**64 - 1}), got {2**64}"),
    ("seed: 3", "seed: -1", "13:9: uncertainty.seed: a seed is a whole number from 0 to 2^64 - 1 "
                            f"({2**64 - 1}), got -1"),
    ("seed: 4}", f"seed: {10**30}}}", "19:58: environment.terrain.synthetic.seed: a seed is a "
                                      f"whole number from 0 to 2^64 - 1 ({2**64 - 1}), got "
                                      f"{10**30}"),
])
def test_a_seed_outside_0_to_2_64_minus_1_is_refused_at_its_place(
        tmp_path: Path, old: str, new: str, expected: str) -> None:
    assert messages(write(tmp_path, GOOD.replace(old, new))) == [expected]


def test_the_largest_seed_is_accepted(tmp_path: Path) -> None:
    text = GOOD.replace("seed: 3", f"seed: {2**64 - 1}").replace("seed: 4}", f"seed: {2**64 - 1}}}")
    campaign = load_campaign(write(tmp_path, text))
    assert campaign.seed == 2**64 - 1


@pytest.mark.parametrize(("slope", "ok"), [("0 deg", True), ("89.99 deg", True),
                                           ("90 deg", False), ("-0.01 deg", False)])
def test_a_synthetic_slope_is_an_inclination_from_0_to_under_90_degrees(slope, ok):
    from pydantic import ValidationError

    from idefix_rules.campaign.input.environment_section import SyntheticTerrain

    if ok:
        assert SyntheticTerrain.model_validate({"slope": slope}).slope >= 0.0
    else:
        with pytest.raises(ValidationError, match="inclination from 0 deg to under 90 deg"):
            SyntheticTerrain.model_validate({"slope": slope})


def test_the_limits_added_for_new_runs_accept_what_lies_just_inside():
    """Each check refusing a value has its accepted side pinned (the refused side is in
    tests/cli/test_cli_user_errors.py), and a stored campaign is read whatever they say."""
    from pydantic import TypeAdapter, ValidationError

    from idefix_rules.campaign.input.environment_section import RockSpec
    from idefix_rules.campaign.input.expectations import MeanRiskExpectation
    from idefix_rules.campaign.input.field_types import STORED_CAMPAIGN
    from idefix_rules.campaign.input.schema import PathName

    names = TypeAdapter(PathName)
    assert names.validate_python("p" * 100) == "p" * 100
    with pytest.raises(ValidationError, match="at most 100 characters"):
        names.validate_python("p" * 101)
    assert names.validate_python("p" * 101, context=STORED_CAMPAIGN) == "p" * 101
    for risk, ok in (("100 %", True), ("0 %", True), ("100.001 %", False), (1, True),
                     (1.00001, False)):
        if ok:
            assert MeanRiskExpectation.model_validate(
                {"path": "p", "max_mean_risk": risk}).max_mean_risk <= 1.0
        else:
            with pytest.raises(ValidationError, match="from 0 to 100 %"):
                MeanRiskExpectation.model_validate({"path": "p", "max_mean_risk": risk})
    rock = {"x": "0 m", "y": "0 m", "radius": "5 cm"}
    assert RockSpec.model_validate({**rock, "embed": "9.99 cm"}).embed == pytest.approx(0.0999)
    assert RockSpec.model_validate({**rock, "embed": "0 m"}).embed == 0.0
    with pytest.raises(ValidationError, match=r"under the rock's height 10 cm \(fully buried\), "
                                              r"got 10 cm"):
        RockSpec.model_validate({**rock, "embed": "10 cm"})
    assert RockSpec.model_validate({**rock, "embed": "10 cm"}, context=STORED_CAMPAIGN)
    # no level: refused for a new run, read back from a campaign stored before the check
    from idefix_rules.campaign.input.expectations import CollisionExpectation

    assert CollisionExpectation.model_validate(
        {"path": "p", "max_collision_chance": {"L2": "0 %"}}).max_collision_chance == {"L2": 0}
    with pytest.raises(ValidationError, match="give at least one level"):
        CollisionExpectation.model_validate({"path": "p", "max_collision_chance": {}})
    assert CollisionExpectation.model_validate(
        {"path": "p", "max_collision_chance": {}}, context=STORED_CAMPAIGN)


@pytest.mark.parametrize("written", ["auto", "AUTO", "Auto", " auto "])
def test_runs_auto_is_read_in_any_case_as_the_command_line_reads_it(
        tmp_path: Path, written: str) -> None:
    campaign = load_campaign(write(tmp_path, GOOD.replace("runs: 8", f"runs: '{written}'")))
    assert campaign.model.runs == "auto"


def test_a_word_other_than_auto_is_still_refused(tmp_path: Path) -> None:
    found = messages(write(tmp_path, GOOD.replace("runs: 8", "runs: automatic")))
    assert any("expected a whole number of runs from 1 to" in m and "'auto', got" in m
               for m in found), found


def test_a_misspelt_key_gets_the_key_meant_and_every_mistake_is_said_at_once(
        tmp_path: Path) -> None:
    assert "expect:" in GOOD
    text = GOOD.replace("runs: 8", "runz: 8").replace("path: straight", "path: nowhere", 1)
    with pytest.raises(UserInputError) as caught:
        load_campaign(write(tmp_path, text))
    found = {d.code: d for d in caught.value.diagnostics}
    assert found["C100"].message == "runz: unknown key"
    assert found["C100"].hint == "did you mean 'runs'?"
    # the expectation's unknown path, said with the schema's mistake (it waited for a fix)
    assert found["C202"].message.startswith("expect[2].path: unknown path 'nowhere'")
    nested = GOOD + "simulation: {output_intervall: 0.1 s}\n"
    with pytest.raises(UserInputError) as caught:
        load_campaign(write(tmp_path, nested))
    (diagnostic,) = caught.value.diagnostics
    assert diagnostic.hint == "did you mean 'output_interval'?"


def test_yes_no_on_off_are_names_where_names_are_meant_and_flags_where_flags_are(
        tmp_path: Path) -> None:
    """The campaign's YAML reads only true/false as booleans (YAML 1.2): a path named `yes`
    and a keep-out area named `off` keep their names (YAML 1.1 made them booleans, refused as
    'not a valid string'); a flag still takes yes/no/on/off; anything else is no flag."""
    text = GOOD.replace("  straight:\n", "  yes:\n").replace(
        "  - {path: straight,", "  - {path: 'yes',").replace(
        "uncertainty:\n", "uncertainty:\n  paired: no\n").replace(
        "  rocks:\n", "  keep_out:\n    - {name: off, level: L3, polygon: [[\"1 m\", \"1 m\"], "
        "[\"1.2 m\", \"1 m\"], [\"1.2 m\", \"1.2 m\"]]}\n  rocks:\n")
    campaign = load_campaign(write(tmp_path, text))
    assert [p.name for p in campaign.paths] == ["yes", "detour"]
    assert campaign.model.uncertainty.paired is False
    assert [area.name for area in campaign.model.environment.keep_out] == ["off"]
    for word, paired in (("on", True), ("Off", False), ("true", True), ("FALSE", False)):
        flagged = load_campaign(write(tmp_path, GOOD.replace(
            "uncertainty:\n", f"uncertainty:\n  paired: {word}\n"), f"c{word}.yaml"))
        assert flagged.model.uncertainty.paired is paired
    refused = messages(write(tmp_path, GOOD.replace("uncertainty:\n",
                                                    "uncertainty:\n  paired: maybe\n"), "m.yaml"))
    assert any("uncertainty.paired" in m and "boolean" in m for m in refused)


@pytest.mark.parametrize(("entry", "expected", "hint"), [
    # the kind's key is pydantic's tag too: the unknown key is the one said, not the kind
    ('{path: detour, verdict: fail, rank: 1}', ["23:35: expect[0].rank: unknown key"], None),
    ('{path: detour, max_mean_risk: "50 %", pth: x}', ["23:43: expect[0].pth: unknown key"],
     "did you mean 'path'?"),
    ('{path: detour, max_collision_chance: {L2: "10 %"}, color: red}',
     ["23:56: expect[0].color: unknown key"], None),
    ('{rank_first: detour, pth: x}', ["23:26: expect[0].pth: unknown key"], None),
    # an entry of no kind: the kind it lacks and the key it has instead, with the key meant
    ('{path: detour, rank: 1}',
     ["23:5: expect[0]: an expectation needs one of: verdict, rank_first, max_mean_risk, "
      "max_collision_chance", "23:20: expect[0].rank: unknown key"], "did you mean 'rank_first'?"),
    # the kind's own value and a key the kind misses are still said at their place
    ('{path: detour, verdict: maybe}',
     ["23:29: expect[0].verdict: expected 'pass', 'fail' or 'marginal', got 'maybe'"], None),
    ('{verdict: fail}', ["23:5: expect[0].path: missing required key"], None),
    ('{max_collision_chance: {L2: "10 %"}}', ["23:5: expect[0].path: missing required key"],
     None),
    # a key inside the kind's own mapping named like the entry's keys: said inside it
    ('{path: detour, max_collision_chance: {L1: 0.1, path: 3}}',
     ["23:52: expect[0].max_collision_chance.path: expected 'L1', 'L2', 'L3' or 'any', "
      "got 'path'", "23:58: expect[0].max_collision_chance.path: expected a risk or chance "
      'from 0 to 100 %, got 300 % (a bare number is a fraction: write "30 %" or 0.3)'], None),
    # no level at all: it would hold with nothing checked (a CI pass on any chain)
    ('{path: detour, max_collision_chance: {}}',
     ['23:42: expect[0].max_collision_chance: give at least one level with its largest '
      'chance, e.g. {L2: "10 %"} (levels: L1, L2, L3, any)'], None),
    ('{path: detour, max_collision_chance: {any: 0.1, verdict: 0.2}}',
     ["23:53: expect[0].max_collision_chance.verdict: expected 'L1', 'L2', 'L3' or 'any', "
      "got 'verdict'"], None),
    ('{path: detour, max_collision_chance: {L2: "110 %"}}',
     ['23:47: expect[0].max_collision_chance.L2: expected a risk or chance from 0 to 100 %, '
      'got 110 % (a bare number is a fraction: write "30 %" or 0.3)'], None),
])
def test_an_unknown_key_of_an_expectation_is_said_at_that_key(
        tmp_path: Path, entry: str, expected: list[str], hint: str | None) -> None:
    text = GOOD.replace("  - {path: detour, verdict: pass}", f"  - {entry}")
    with pytest.raises(UserInputError) as caught:
        load_campaign(write(tmp_path, text))
    found = caught.value.diagnostics
    assert [f"{d.span.line}:{d.span.column}: {d.message}" for d in found] == expected
    assert found[-1].hint == hint


@pytest.mark.parametrize(("size", "refused"), [
    ({"radius": "1000 m"}, False), ({"radius": "1 km", "embed": "1999 m"}, False),
    ({"semi_axes": ["1 cm", "1000 m", "1 cm"]}, False),
    ({"radius": "1000.001 m"}, True), ({"semi_axes": ["1 cm", "1 cm", "1e200 m"]}, True),
])
def test_a_rock_is_at_most_1_km_in_radius_or_semi_axis(size: dict[str, object],
                                                       refused: bool) -> None:
    """Larger, it is terrain, and its squares overflowed the obstacle checker's geometry
    (a rock 1e200 m wide was met by no collision test); a stored campaign is read as it ran."""
    from pydantic import ValidationError

    from idefix_rules.campaign.input.environment_section import RockSpec
    from idefix_rules.campaign.input.field_types import STORED_CAMPAIGN

    rock = {"x": "0 m", "y": "0 m", **size}
    if not refused:
        assert max(RockSpec.model_validate(rock).axes) == pytest.approx(1000.0)
        return
    with pytest.raises(ValidationError, match="expected a rock radius or semi-axis of at most "
                                              "1000 m"):
        RockSpec.model_validate(rock)
    assert RockSpec.model_validate(rock, context=STORED_CAMPAIGN)


@pytest.mark.parametrize(("old", "new", "expected"), [
    ("  terrain:\n", "  terrain: 5\n  xterrain:\n",
     "18:12: environment.terrain: expected a mapping (key: value), got 5"),
    ('    - {max_wheel_rate: "0.05 rad/s", delta_position: "1 m", delta_heading: "0 deg"}',
     "    - 5", "7:7: paths.straight[0]: expected a mapping (key: value), got 5"),
    ("uncertainty:\n", "uncertainty: [seed]\nx:\n",
     "11:14: uncertainty: expected a mapping (key: value), got [seed]"),
])
def test_a_section_that_is_no_mapping_is_said_without_the_schema_s_class_names(
        tmp_path: Path, old: str, new: str, expected: str) -> None:
    assert old in GOOD
    found = messages(write(tmp_path, GOOD.replace(old, new, 1)))
    assert expected in found
    assert not any("instance of" in message for message in found), found


WAIVER = ("waivers:\n  - {rule: acceptable_risk, path: detour, reason: survey, "
          "approved_by: J. Doe, until: UNTIL}\n")


@pytest.mark.parametrize(("old", "new", "expected", "hint"), [
    # pydantic's "Unable to extract tag using discriminator 'distribution'"
    ('initial.x: {distribution: normal, mean: "0 m", std: "1 cm"}', "initial.x: {}",
     "15:16: uncertainty.parameters.initial.x.distribution: missing required key: which "
     "distribution, one of 'fixed', 'normal', 'truncated_normal', 'uniform' or 'log_normal'",
     'for example {distribution: normal, mean: "0 m", std: "1 cm"}'),
    ("distribution: normal", "distribution: true",
     "15:31: uncertainty.parameters.initial.x: unknown distribution 'true' (expected one of: "
     "'fixed', 'normal', 'truncated_normal', 'uniform', 'log_normal')", None),
    # "Input should be a valid list": a path, expect or waivers without a value
    ('  straight:\n    - {max_wheel_rate: "0.05 rad/s", delta_position: "1 m", '
     'delta_heading: "0 deg"}\n', "  straight:\n",
     "6:12: paths.straight: expected a list, got nothing",
     'for example [{max_wheel_rate: "0.05 rad/s", delta_position: "1 m", delta_heading: '
     "\"0 deg\"}], or one command per '- ' line"),
    (GOOD[GOOD.index("expect:"):], "expect:\n", "22:8: expect: expected a list, got nothing",
     "for example expect: [{path: straight, verdict: pass}], or expect: [] for none"),
    (GOOD[GOOD.index("expect:"):], "waivers:\n", "22:9: waivers: expected a list, got nothing",
     'for example waivers: [{rule: max_turn, path: detour, reason: "…", approved_by: NAME, '
     "until: 2027-03-31}], or waivers: [] for none"),
    ("  rocks:\n    - {x: \"0.5 m\", y: \"-0.26 m\", radius: \"5 cm\", level: L2}\n",
     "  rocks: big\n", "20:10: environment.rocks: expected a list, got 'big'",
     'for example rocks: [{x: "0.5 m", y: "0 m", radius: "5 cm"}], or rocks: [] for none'),
    # "Input should be a valid integer"
    ("seed: 3", "seed: 1.5", "13:9: uncertainty.seed: expected a whole number, got 1.5",
     "for example seed: 3"),
    ("runs: 8", "runs: auto\nmax_runs: 0x1p3",
     "4:11: max_runs: expected a whole number, got '0x1p3'", "for example max_runs: 1000"),
    # "Input should be a valid tuple"
    ("synthetic: {slope:", 'origin: "-2 m"\n    synthetic: {slope:',
     "19:13: environment.terrain.origin: expected a list of 2 values, got '-2 m'",
     'for example origin: ["-2 m", "-2 m"] (x, y)'),
    ("  rocks:\n", '  keep_out:\n    - {name: k, polygon: ["1 m", ["1 m", "0 m"], ["0 m", '
                   '"1 m"]]}\n  rocks:\n',
     "21:27: environment.keep_out[0].polygon[0]: expected a list of 2 values, got '1 m'",
     'for example ["1 m", "0 m"] (x, y)'),
    # "Input should be a valid string": a name YAML read as a number
    ("name: demo", "name: 1.5", "1:7: name: expected text, got 1.5",
     'quote it to keep it as text: "1.5"'),
    ("rulebook: demo.rules", "rulebook: [demo.rules]",
     "2:11: rulebook: expected text, got [demo.rules]", None),
    # dates: "Datetimes provided to dates should have zero time", "Input should be a valid date"
    (GOOD[GOOD.index("expect:"):], WAIVER.replace("UNTIL", "2027-03-31 12:00:00"),
     "23:87: waivers[0].until: expected a date without a time of day, got 2027-03-31 12:00:00 "
     "(a waiver holds up to and including the day it names)", "for example until: 2027-03-31"),
    (GOOD[GOOD.index("expect:"):], WAIVER.replace("UNTIL", "end of March"),
     "23:87: waivers[0].until: expected a date written YYYY-MM-DD, got 'end of March'",
     "for example until: 2027-03-31"),
    (GOOD[GOOD.index("expect:"):], WAIVER.replace("UNTIL", "[2027-03-31]"),
     "23:87: waivers[0].until: expected a date written YYYY-MM-DD, got [2027-03-31]",
     "for example until: 2027-03-31"),
    # "Input should be a valid boolean"
    ("uncertainty:\n", "uncertainty:\n  paired: 2\n",
     "12:11: uncertainty.paired: expected a boolean: true or false (or yes/no, on/off), got 2",
     "for example paired: false"),
])
def test_a_value_of_the_wrong_type_says_what_is_expected_with_an_example(
        tmp_path: Path, old: str, new: str, expected: str, hint: str | None) -> None:
    """pydantic's own words ("Input should be a valid list") named neither what the campaign
    expects there nor how to write it."""
    assert old in GOOD
    with pytest.raises(UserInputError) as caught:
        load_campaign(write(tmp_path, GOOD.replace(old, new, 1)))
    found = [(f"{d.span.line}:{d.span.column}: {d.message}", d.hint)
             for d in caught.value.diagnostics if d.code == "C100"]
    assert found == [(expected, hint)]
