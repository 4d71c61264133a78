"""Obstacle shapes for the map: levels and buffers from the stored campaign and rulebook."""

from __future__ import annotations

import numpy as np
import pytest
from report_fixture import CAMPAIGN, RULEBOOK

from idefix_rules.report.environment import AreaShape, buffer_mask, map_environment
from idefix_rules.rulebook import check_text


def test_buffer_mask_holds_the_area_and_points_closer_than_the_margin() -> None:
    square = AreaShape("square", np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]]),
                       "L3", 0.2)
    xs, ys, mask = buffer_mask(square, 0.05)

    def at(x: float, y: float) -> float:
        return float(mask[np.argmin(np.abs(ys - y)), np.argmin(np.abs(xs - x))])

    assert at(0.5, 0.5) == 1.0  # inside
    assert at(1.15, 0.5) == 1.0  # 0.15 m outside an edge: within 0.2 m
    assert at(1.3, 0.5) == 0.0  # 0.3 m outside
    assert at(1.17, 1.17) == 0.0  # 0.24 m from the corner: the buffer is rounded there
    assert at(1.1, 1.1) == 1.0  # 0.14 m from the corner


def test_rocks_and_areas_from_the_stored_campaign() -> None:
    checked = check_text(RULEBOOK, "report-test.rules").checked
    environment, notes = map_environment(CAMPAIGN, checked)
    assert notes == []
    (rock,) = environment.rocks
    assert (rock.name, rock.level) == ("rock1", "L2")
    assert (rock.x, rock.y, rock.a, rock.b) == pytest.approx((0.5, -0.26, 0.06, 0.06))
    assert rock.buffer == pytest.approx(0.05)  # the rulebook's L2 buffer
    (area,) = environment.areas
    assert (area.name, area.level) == ("crater", "L3") and area.buffer == pytest.approx(0.1)
    assert environment.bounds() == pytest.approx((0.39, 1.2, -0.37, 0.8))


def test_an_unreadable_environment_is_a_note_not_an_error() -> None:
    environment, notes = map_environment("environment: {rocks: [{x: 1}]}", None)
    assert environment.rocks == () and "could not be read" in notes[0]


def test_an_area_named_off_is_drawn_as_the_campaign_read_it() -> None:
    """The campaign reads only true/false as booleans (YAML 1.2): an area named `off` is a
    name there, and the report reads the stored campaign the same way (it dropped every
    obstacle, the environment unreadable with a boolean for a name)."""
    checked = check_text(RULEBOOK, "report-test.rules").checked
    text = CAMPAIGN.replace("    - name: crater", "    - name: off")
    assert text != CAMPAIGN
    environment, notes = map_environment(text, checked)
    assert notes == [] and [area.name for area in environment.areas] == ["off"]
    assert len(environment.rocks) == 1


def test_the_rulebooks_areas_are_drawn_with_the_polygons_the_campaign_gives_them() -> None:
    """`environment.areas` polygons of the rulebook's keep-out and unknown areas were not drawn
    (only `environment.keep_out` was): the map showed contacts with nothing there."""
    rulebook = RULEBOOK.replace("obstacles {", "obstacles {\n  area pit keep_out level L3 buffer "
                                "10 cm because \"A pit\"\n  area dark unknown level L2 buffer "
                                "30 cm because \"Not seen\"", 1)
    assert rulebook != RULEBOOK
    checked = check_text(rulebook, "report-test.rules").checked
    assert checked is not None
    text = CAMPAIGN.replace("environment:\n", "environment:\n  areas:\n"
                            '    pit: {polygons: [[["0.8 m", "0 m"], ["1 m", "0 m"], '
                            '["1 m", "0.2 m"]]]}\n'
                            '    dark: {polygons: [[["2 m", "0 m"], ["3 m", "0 m"], '
                            '["3 m", "1 m"]], [["4 m", "0 m"], ["5 m", "0 m"], ["5 m", "1 m"]]]}\n',
                            1)
    assert text != CAMPAIGN
    environment, notes = map_environment(text, checked)
    assert notes == []
    drawn = [(a.name, a.level, round(a.buffer, 3)) for a in environment.areas]
    assert drawn == [("crater", "L3", 0.1), ("pit", "L3", 0.1), ("dark", "L2", 0.3),
                     ("", "L2", 0.3)]
