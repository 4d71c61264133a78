"""Assumed vs simulated slip: the reference run's effective slip beside theoretical_slip."""

from __future__ import annotations

import json

import h5py
import numpy as np
import pytest

from idefix_rules.campaign.evaluation.slip import (
    SLIP_MARGIN,
    SlipCheck,
    effective_slip,
    mean_wheel_slip,
    slip_measurement,
    stored_records,
    unmeasured_text,
)
from idefix_rules.commands import Command


def _straight(travelled: float, samples: int = 11) -> dict[str, np.ndarray]:
    """A reference run that drives ``travelled`` m along x during command 0, then stops."""
    x = np.append(np.linspace(0.0, travelled, samples - 1), travelled)
    command = np.append(np.zeros(samples - 1), -1)
    return {"x": x, "y": np.zeros(samples), "yaw": np.zeros(samples), "command": command,
            "wheel.slip": np.full((samples, 4), 0.1)}


@pytest.mark.parametrize(("travelled", "expected"), [(1.0, 0.0), (0.8, 0.2), (0.97, 0.03),
                                                      (1.1, -0.1)])
def test_the_effective_slip_is_the_share_of_commanded_travel_not_driven(travelled, expected):
    chain = (Command(0.05, 1.0, 0.0),)
    assert effective_slip(_straight(travelled), chain) == pytest.approx(expected)


def test_point_turns_measure_slip_on_the_heading():
    yaw = np.append(np.linspace(0.0, 0.9 * np.pi / 2, 10), 0.9 * np.pi / 2)
    reference = {"x": np.zeros(11), "y": np.zeros(11), "yaw": yaw,
                 "command": np.append(np.zeros(10), -1)}
    assert effective_slip(reference, (Command(0.05, 0.0, np.pi / 2),)) == pytest.approx(0.1)
    assert effective_slip({"x": np.zeros(3)}, (Command(0.05, 1.0, 0.0),)) is None


def test_the_mean_wheel_slip_counts_only_driving_samples():
    reference = _straight(1.0)
    reference["wheel.slip"][-1] = 0.9  # after the last command: not counted
    assert mean_wheel_slip(reference) == pytest.approx(0.1)


@pytest.mark.parametrize(("measured", "warns"), [
    (0.2 - SLIP_MARGIN + 0.001, False),  # just inside the margin
    (0.2 + SLIP_MARGIN - 0.001, False),
    (0.2 - SLIP_MARGIN - 0.001, True),  # just outside
    (0.2 + SLIP_MARGIN + 0.001, True),
    (None, False),  # nothing measured: nothing to compare
])
def test_a_warning_comes_only_outside_the_margin_and_names_the_setting(measured, warns):
    check = SlipCheck("straight", 0.2, measured, None, rulebook="rulebook r 1.0.0")
    assert check.disagrees is warns
    if warns:
        assert check.warning is not None
        assert "theoretical_slip" in check.warning and "rulebook r 1.0.0" in check.warning
        assert f"set `theoretical_slip = {100 * measured:.0f} %`" in check.warning
    else:
        assert check.warning is None
    assert json.dumps(check.to_dict())  # JSON-ready


def test_a_negative_measured_slip_suggests_zero():
    check = SlipCheck("downhill", 0.2, -0.04, None)
    assert check.warning is not None and "set `theoretical_slip = 0 %`" in check.warning


def test_the_report_shows_assumed_and_measured_slip_and_the_warnings(tmp_path):
    from idefix_rules.report.html import slip_html

    summary = {"slip": {"paths": [SlipCheck("a", 0.2, 0.01, None).to_dict(),
                                  SlipCheck("b", 0.2, 0.19, 0.18).to_dict()]}}
    with h5py.File(tmp_path / "r.h5", "w") as file:
        file.create_group("evaluation").attrs["summary"] = json.dumps(summary)
        records = stored_records(file)
    assert [r["path"] for r in records] == ["a", "b"]
    page = slip_html(records)
    assert "Assumed vs simulated slip" in page and "theoretical_slip" in page
    assert page.count("class=\"note\"") == 1  # only path a disagrees
    assert "a: the reference run slipped 1.0 %" in page
    assert ">19.0<" in page and ">18.0<" in page and ">20.0<" in page


@pytest.mark.parametrize(("reference", "chain", "reason"), [
    ({"x": np.zeros(3), "y": np.zeros(3)}, (Command(0.05, 1.0, 0.0),),
     "the reference run has no 'command' (the FMU's signal map does not provide it), so which "
     "command was active at each sample is not known"),
    ({"command": np.zeros(3)}, (Command(0.05, 1.0, 0.0),),
     "the reference run has no 'x', 'y' (the FMU's signal map does not provide them)"),
    (_straight(1.0), (Command(0.05, 0.0, 0.0),), "the chain commands no motion"),
    ({k: v for k, v in _straight(0.0).items() if k != "yaw"}, (Command(0.05, 0.0, 1.0),),
     "the chain only turns on the spot and the reference run has no 'yaw'"),
])
def test_a_reference_run_that_gives_no_slip_says_why(reference, chain, reason):
    measured, why = slip_measurement(reference, chain)
    assert measured is None and why is not None and why.startswith(reason)


def test_a_slip_not_measured_neither_agrees_nor_disagrees_and_says_why(tmp_path):
    """A foreign FMU's map without 'command': the report said "agree" (in green) of a slip
    nobody measured, the console nothing."""
    from idefix_rules.report.html import slip_html

    reason = "the reference run has no 'command'"
    unmeasured = SlipCheck("a", 0.0, None, None, not_measured=reason)
    record = unmeasured.to_dict()
    assert record["disagrees"] is False and record["warning"] is None
    assert record["not_measured"] == reason
    assert SlipCheck("b", 0.0, 0.01, None).to_dict()["not_measured"] is None
    assert unmeasured_text([unmeasured, SlipCheck("b", 0.0, 0.01, None)]) == \
        f"not measured for a: {reason}"
    assert unmeasured_text([SlipCheck("b", 0.0, 0.01, None)]) is None
    page = slip_html([record, SlipCheck("b", 0.0, 0.01, None).to_dict()])
    assert page.count(">agree<") == 1  # b only
    assert ">not measured<" in page and "the reference run has no &#x27;command&#x27;" in page
    # a record stored before the reason was: not measured all the same
    old = {key: value for key, value in record.items() if key != "not_measured"}
    assert ">agree<" not in slip_html([old]) and ">not measured<" in slip_html([old])
