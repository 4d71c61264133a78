"""A regolith key the FMU has no soil parameter for names the regolith keys there are (the
soil parameters without `soil.`), not a full FMU name the regolith does not take."""

from __future__ import annotations

from pathlib import Path

import pytest

from idefix_rules.cli import main

ROOT = Path(__file__).parents[2]


def _campaign(tmp_path: Path, key: str) -> Path:
    text = (ROOT / "campaigns" / "flat-control.yaml").read_text()
    text = text.replace("../rulebooks/", f"{ROOT / 'rulebooks'}/").replace(
        "output: ../results/flat-control", f"output: {tmp_path / 'out'}")
    assert "    n: 1.0\n" in text
    path = tmp_path / "campaign.yaml"
    path.write_text(text.replace("    n: 1.0\n", f'    n: 1.0\n    {key}: "10 %"\n'))
    return path


@pytest.mark.parametrize(("key", "hint"), [
    ("slip", "regolith keys are"),                     # no soil parameter of that name
    ("cohesio", "did you mean 'cohesion'? regolith keys are"),
])
def test_an_unknown_regolith_key_names_the_keys_there_are(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], key: str, hint: str) -> None:
    path = _campaign(tmp_path, key)
    assert main([str(path), "--runs", "2", "--quiet", "--no-report"]) == 2
    output = " ".join("".join(capsys.readouterr()).split())
    assert f"error[C401]: environment.regolith.{key}: unknown FMU parameter 'soil.{key}'" in output
    assert hint in output and "k_phi" in output and "did you mean 'soil." not in output
