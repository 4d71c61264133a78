"""An output interval longer than a run is refused before anything is simulated (C404): the
stop time is rounded up to a whole interval, so such a run would be one sample, simulated for
the whole interval (1e9 s)."""

from __future__ import annotations

from pathlib import Path

import pytest

from idefix_rules.campaign.input.campaign_values import rover_geometry, stop_limit
from idefix_rules.campaign.input.load import load_campaign
from idefix_rules.campaign.input.validate import check_simulation_size
from idefix_rules.errors import UserInputError

ROOT = Path(__file__).parents[2]


def _campaign(tmp_path: Path, interval: str) -> Path:
    text = (ROOT / "campaigns" / "flat-control.yaml").read_text()
    text = text.replace("../rulebooks/", f"{ROOT / 'rulebooks'}/")
    if "output_interval" in text:
        text = text.replace('output_interval: "0.1 s"', f'output_interval: "{interval}"')
    else:
        text += f'\nsimulation:\n  output_interval: "{interval}"\n'
    path = tmp_path / f"c{len(list(tmp_path.iterdir()))}.yaml"
    path.write_text(text)
    return path


def test_the_longest_output_interval_is_the_shortest_run(tmp_path: Path) -> None:
    base = load_campaign(_campaign(tmp_path, "0.1 s"))
    rover = rover_geometry(base)
    settings = base.model.simulation
    shortest = min(stop_limit(base, spec.chain, rover)[2] for spec in base.paths) \
        * settings.duration_margin + settings.extra_time
    check_simulation_size(load_campaign(_campaign(tmp_path, f"{shortest!r} s")))  # inside
    with pytest.raises(UserInputError) as refused:
        check_simulation_size(load_campaign(_campaign(tmp_path, f"{shortest * 1.001:.12g} s")))
    (diagnostic,) = refused.value.diagnostics
    assert diagnostic.code == "C404" and "simulation.output_interval" in diagnostic.message
    assert diagnostic.span is not None and diagnostic.span.line > 0
    with pytest.raises(UserInputError):
        check_simulation_size(load_campaign(_campaign(tmp_path, "1e9 s")))
