"""The FMU's declared interface: generated files in sync, units and descriptions, validation."""

from __future__ import annotations

from pathlib import Path

from idefix_rules.fmu.build import source_dir
from idefix_rules.fmu.variables import (
    VARIABLES,
    render_header,
    render_model_description,
    render_signal_map,
)
from idefix_rules.signals import FMU_SIGNALS


def test_generated_files_match_the_variable_table() -> None:
    src = source_dir()
    assert (src / "modelDescription.xml").read_text(encoding="utf-8") == render_model_description()
    assert (src / "sources" / "variables.h").read_text(encoding="utf-8") == render_header()
    assert (src / "signal_map.json").read_text(encoding="utf-8") == render_signal_map()


def test_every_real_has_a_unit_and_every_variable_a_description() -> None:
    for variable in VARIABLES:
        assert variable.description.strip(), variable.name
        if variable.kind == "Real":
            assert variable.unit, variable.name


def test_fmpy_validate_reports_no_problems(rover_fmu: Path) -> None:
    from fmpy.validation import validate_fmu

    assert validate_fmu(str(rover_fmu)) == []


def test_default_signal_map_covers_the_fmu_part_of_the_contract() -> None:
    import json

    mapping = json.loads((source_dir() / "signal_map.json").read_text(encoding="utf-8"))
    covered = {name.split("[")[0] for name in mapping.values()}
    # 'done' is for FMUs without 'command' (bring your own FMU); the rover reports 'command'.
    assert covered == set(FMU_SIGNALS) - {"done"}


def test_rover_model_doc_documents_every_parameter() -> None:
    doc = (Path(__file__).resolve().parents[2] / "docs" / "rover-model.md").read_text(
        encoding="utf-8")
    for variable in VARIABLES:
        if variable.causality == "parameter":
            name = variable.name.split("[")[0] + ("[i]" if "[" in variable.name else "")
            assert f"`{name}`" in doc, name
