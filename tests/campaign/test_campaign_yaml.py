"""How a campaign's YAML is read: merge keys (``<<``) and keys that must be names."""

from __future__ import annotations

import textwrap
from pathlib import Path

import pytest

from idefix_rules.campaign.input.load import load_campaign
from idefix_rules.campaign.input.yamlsource import load_yaml, yaml_data
from idefix_rules.errors import UserInputError

CAMPAIGN = """\
rulebook: demo.rules
paths:
  straight:
    - &cmd {max_wheel_rate: "0.05 rad/s", delta_position: "1 m", delta_heading: "0 deg"}
uncertainty:
  parameters:
    initial.x: &n {distribution: normal, mean: "0 m", std: "1 cm"}
"""


def write(tmp_path: Path, text: str) -> Path:
    (tmp_path / "demo.rules").write_text("rulebook \"demo\" version \"1.0.0\"\n")
    path = tmp_path / "campaign.yaml"
    path.write_text(textwrap.dedent(text))
    return path


def problems(tmp_path: Path, text: str) -> list[str]:
    with pytest.raises(UserInputError) as caught:
        load_campaign(write(tmp_path, text))
    return [f"{d.span.line}:{d.span.column}: error[{d.code}]: {d.message}"
            + (f" (hint: {d.hint})" if d.hint else "") for d in caught.value.diagnostics]


# ----------------------------------------------------------------------------- merge keys

def test_a_key_of_the_mapping_overrides_the_one_a_merge_key_gives(tmp_path: Path) -> None:
    text = CAMPAIGN + '    initial.y:\n      <<: *n\n      std: "2 cm"\n'
    parameters = load_campaign(write(tmp_path, text)).model.uncertainty.parameters
    assert parameters["initial.y"].std == pytest.approx(0.02)
    assert parameters["initial.y"].mean == 0.0
    assert parameters["initial.x"].std == pytest.approx(0.01)  # the anchored one unchanged


def test_an_override_may_come_before_the_merge_key_and_in_a_flow_mapping(
        tmp_path: Path) -> None:
    text = CAMPAIGN.replace("uncertainty:", '    - {<<: *cmd, delta_heading: "10 deg"}\n'
                                            "uncertainty:") + \
        '    initial.y: {std: "3 cm", <<: *n}\n'
    campaign = load_campaign(write(tmp_path, text))
    assert campaign.model.uncertainty.parameters["initial.y"].std == pytest.approx(0.03)
    chain = campaign.paths[0].chain
    assert [round(command.delta_heading, 4) for command in chain] == [0.0, 0.1745]
    assert chain[1].delta_position == chain[0].delta_position == 1.0


def test_of_two_merged_mappings_the_first_in_the_list_wins() -> None:
    text = "a: &a {x: 1, y: 1}\nb: &b {x: 2, z: 2}\nc: {<<: [*a, *b], w: 3}\n"
    document = load_yaml(text, "c.yaml")
    assert document.data["c"] == {"x": 1, "y": 1, "z": 2, "w": 3}
    assert yaml_data(text)["c"] == document.data["c"]  # the reader of stored campaigns agrees
    # a merged value is located where it is written: in the anchored mapping
    assert str(document.locations.span(("c", "x"))) == "c.yaml:1:11"
    assert str(document.locations.span(("c", "z"), at_key=True)) == "c.yaml:2:14"
    assert str(document.locations.span(("c", "w"))) == "c.yaml:3:22"


def test_a_merged_mapping_may_merge_another() -> None:
    text = "a: &a {x: 1}\nb: &b {<<: *a, y: 2}\nc: {<<: *b, x: 3}\n"
    assert load_yaml(text, "c.yaml").data == {"a": {"x": 1}, "b": {"x": 1, "y": 2},
                                              "c": {"x": 3, "y": 2}}


def test_a_mistake_in_a_merged_value_is_said_in_the_anchored_mapping(tmp_path: Path) -> None:
    # a rock's keys merged into a command: unknown there, said where they are written
    text = CAMPAIGN.replace("paths:\n", 'rock: &rock {x: "1 m", max_wheel_rate: "1 rad/s"}\n'
                                        "paths:\n") + '    initial.y: {<<: *n, std: "2 parsec"}\n'
    text = text.replace('    - &cmd {max_wheel_rate: "0.05 rad/s", delta_position: "1 m", '
                        'delta_heading: "0 deg"}\n',
                        '    - {<<: *rock, delta_position: "1 m", delta_heading: "0 deg"}\n')
    assert problems(tmp_path, text) == [
        "2:1: error[C100]: rock: unknown key",
        "2:14: error[C100]: paths.straight[0].x: unknown key",
        "9:30: error[C100]: uncertainty.parameters.initial.y.std: unknown unit 'parsec'",
    ]


def test_a_key_written_twice_in_one_mapping_is_still_a_duplicate(tmp_path: Path) -> None:
    text = CAMPAIGN + '    initial.y:\n      <<: *n\n      std: "2 cm"\n      std: "3 cm"\n'
    assert problems(tmp_path, text) == ["11:7: error[C002]: duplicate key 'std'"]
    # also inside a mapping written in the merge key's list
    assert problems(tmp_path, CAMPAIGN + "    initial.y: {<<: [{std: 1, std: 2}]}\n") == [
        "8:31: error[C002]: duplicate key 'std'"]


@pytest.mark.parametrize(("merge", "expected"), [
    ("<<: 5", "8:21: error[C000]: invalid YAML: a merge key '<<' takes a mapping (an alias such "
              "as *name of one) or a list of mappings, got 5"),
    ("<<: [*n, [1]]", "8:26: error[C000]: invalid YAML: a merge key '<<' takes a mapping (an "
                      "alias such as *name of one) or a list of mappings, got a list"),
    ("<<: *n, <<: *n", "8:25: error[C000]: invalid YAML: a second merge key '<<' in one mapping: "
                       "give one, with a list of the mappings to merge (<<: [*first, *second])"),
])
def test_a_merge_key_takes_mappings_once(tmp_path: Path, merge: str, expected: str) -> None:
    assert problems(tmp_path, CAMPAIGN + f"    initial.y: {{{merge}}}\n") == [expected]


def test_a_mapping_merging_itself_is_refused_not_a_recursion() -> None:
    with pytest.raises(UserInputError) as caught:
        load_yaml("c: &c\n  y: 1\n  <<: *c\n", "c.yaml")
    (diagnostic,) = caught.value.diagnostics
    assert (diagnostic.code, str(diagnostic.span), diagnostic.message) == (
        "C000", "c.yaml:1:4", "invalid YAML: a mapping merges itself: '<<' names the mapping "
                              "it stands in")


def test_nested_merges_of_one_mapping_cost_no_more_than_its_keys() -> None:
    lines = ["a0: &a0 {" + ", ".join(f"k{i}: {i}" for i in range(10)) + "}"]
    lines += [f"a{d}: &a{d} {{<<: [{', '.join([f'*a{d - 1}'] * 9)}], own{d}: 1}}"
              for d in range(1, 40)]
    assert len(load_yaml("\n".join(lines), "c.yaml").data["a39"]) == 10 + 39


# ------------------------------------------------------------------- keys that are no names

CHAIN = '[{max_wheel_rate: "0.05 rad/s", delta_position: "1 m", delta_heading: "0 deg"}]'


@pytest.mark.parametrize(("key", "kind"), [
    ("true", "a boolean"), ("False", "a boolean"), ("1", "a whole number"),
    ("-1", "a whole number"), ("0x10", "a whole number"), ("1.5", "a number"),
    (".inf", "a number"), ("2024-01-01", "a date"),
    ("2024-01-01 10:00:00", "a date and time"), ("null", "null (no value)"),
    ("~", "null (no value)"),
])
def test_a_path_named_as_yaml_reads_no_name_is_refused_at_its_key_quoted_in_the_hint(
        tmp_path: Path, key: str, kind: str) -> None:
    text = CAMPAIGN.replace("uncertainty:", f"  {key}: {CHAIN}\nuncertainty:")
    assert problems(tmp_path, text) == [
        f'5:3: error[C001]: the key {key} is read by YAML as {kind}, not as a name (hint: '
        f'quote it to keep it as a name: "{key}")']


@pytest.mark.parametrize(("old", "new", "expected"), [
    # a parameter, a regolith value, an area, a signal, a setting: every key is a name
    ("    initial.x:", "    1: {distribution: fixed, value: 1}\n    initial.x:",
     '7:5: error[C001]: the key 1 is read by YAML as a whole number'),
    ("uncertainty:", "environment:\n  regolith: {true: 1}\nuncertainty:",
     '6:14: error[C001]: the key true is read by YAML as a boolean'),
    ("uncertainty:", "environment:\n  areas:\n    2024-01-01: {polygons: []}\nuncertainty:",
     '7:5: error[C001]: the key 2024-01-01 is read by YAML as a date'),
    ("uncertainty:", "fmu:\n  signals: {.nan: x}\nuncertainty:",
     '6:13: error[C001]: the key .nan is read by YAML as a number'),
    ("rulebook:", "null: x\nrulebook:", '1:1: error[C001]: the key null is read by YAML as null'),
    ("uncertainty:", "simulation:\n  ?\n  : 1\nuncertainty:",
     "6:4: error[C001]: a key is missing before ':' (hint: write the name of what the value "
     "sets before the colon)"),
])
def test_every_key_is_a_name(tmp_path: Path, old: str, new: str, expected: str) -> None:
    (found,) = problems(tmp_path, CAMPAIGN.replace(old, new, 1))
    assert found.startswith(expected), found


def test_names_quoted_are_names_however_yaml_would_read_them_unquoted(tmp_path: Path) -> None:
    """``true`` and ``1`` were one key to Python (True == 1: 'duplicate key 1'), ``0x10`` and
    ``16`` too; a path ``true`` was said as an index (``paths[1]``). Quoted, each is its name."""
    names = ["true", "1", "0x10", "16", "-1", "2024-01-01", "null"]
    text = CAMPAIGN.replace("uncertainty:", "".join(f'  "{name}": {CHAIN}\n' for name in names)
                            + "uncertainty:")
    assert [path.name for path in load_campaign(write(tmp_path, text)).paths] == \
        ["straight", *names]
    # and a mistake in one is said at its name, not at a list index
    broken = text.replace(f'  "true": {CHAIN}', f'  "true": {CHAIN.replace("1 m", "1 parsec")}')
    assert problems(tmp_path, broken) == [
        "5:59: error[C100]: paths.true[0].delta_position: unknown unit 'parsec'"]
