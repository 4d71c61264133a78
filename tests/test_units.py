import math

import pytest

from idefix_rules.units import (
    ANGLE,
    CHARGE,
    DIMENSIONLESS,
    LENGTH,
    UnitError,
    convert,
    describe,
    parse_quantity,
    parse_unit,
)


def test_percent_and_ratio_convert_exactly():
    assert parse_quantity("70 %").value == 0.7
    assert parse_quantity("20 %").value == 0.2
    assert parse_quantity("0.7").dimension == DIMENSIONLESS


def test_degrees_and_radians_convert_exactly():
    assert parse_quantity("90 deg").value == math.pi / 2
    assert parse_quantity("180 deg").value == math.pi
    assert convert(math.pi, "rad", "deg") == 180.0


def test_milliamp_seconds_are_charge():
    assert parse_unit("mAs").dimension == CHARGE == parse_unit("A·s").dimension
    assert parse_quantity("648.32 mAs").value == 0.64832
    assert convert(1.0, "A*s", "mAs") == 1000.0


def test_compound_units():
    assert parse_unit("cm/rad").dimension == LENGTH / ANGLE
    assert parse_quantity("3 mm/s").value == 0.003
    assert parse_unit("m/s^2").scale == 1.0


@pytest.mark.parametrize("text", ["5 furlongs", "cm/", "", "/s"])
def test_bad_units_are_rejected(text):
    with pytest.raises(UnitError):
        parse_unit(text)


def test_incompatible_conversion_names_both_dimensions():
    with pytest.raises(UnitError, match=r"a length.*an angle"):
        convert(1.0, "cm", "deg")
    assert describe(ANGLE) == "an angle"
