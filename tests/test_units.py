import math

import pytest
from hypothesis import event, given
from hypothesis import strategies as st

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


@pytest.mark.parametrize(("text", "position", "named"), [
    ("\uff170 %", 0, "FULLWIDTH DIGIT SEVEN"), ("7\uff10 %", 1, "FULLWIDTH DIGIT ZERO"),
    ("\u0663 m", 0, "ARABIC-INDIC DIGIT THREE"), ("1 m^\uff12", 4, "FULLWIDTH DIGIT TWO")])
def test_digits_of_another_script_are_refused_where_they_stand(text, position, named):
    with pytest.raises(UnitError, match=named) as failure:
        parse_quantity(text)
    assert failure.value.position == position
    assert "0-9" in str(failure.value)


def test_a_unit_power_in_another_script_is_refused():
    with pytest.raises(UnitError, match="FULLWIDTH DIGIT TWO"):
        parse_unit("m^\uff12")


@pytest.mark.parametrize("text", ["1e-400", "1e-400 %", "-2.5e-999 m", "5e-324 mm"])
def test_a_nonzero_number_that_would_be_read_as_0_is_refused(text):
    with pytest.raises(UnitError, match="too small for a double"):
        parse_quantity(text)


@pytest.mark.parametrize("text", ["0e-400", "0.0e-999 m", "1e-300 %", "4.9e-324"])
def test_zero_and_numbers_a_double_holds_are_read(text):
    assert (parse_quantity(text).value == 0) == (float(text.split()[0]) == 0)


@pytest.mark.parametrize(("text", "same_as"), [
    ("7.4 cm", "74 mm"), ("4.1 cm", "0.041 m"), ("1.1 %", "0.011"), ("29.1 %", "0.291"),
    ("648.32 mAs", "0.64832 As"), ("2.5 min", "150 s")])
def test_a_decimal_converts_as_written_not_as_its_binary_value(text, same_as):
    """7.4 as a double is 7.4000000000000003552…: scaled by 1/100 and rounded it was
    0.07400000000000001, one ulp above 0.074, so `>= 7.4 cm` missed a sinkage of 74 mm."""
    assert parse_quantity(text).value == parse_quantity(same_as).value


@given(st.integers(min_value=1, max_value=10**9), st.integers(min_value=0, max_value=6),
       st.sampled_from(["%", "cm", "mm", "um", "km", "g", "ms", "mA", "mAs", "mAh", "mrad",
                        "mN"]))
def test_every_decimal_is_the_double_nearest_its_exact_value_in_si(digits, places, unit):
    from fractions import Fraction
    text = f"{digits / 10**places:.{places}f}" if places else str(digits)
    exact = Fraction(text) * parse_unit(unit).exact_scale
    value = parse_unit(unit).to_si(float(text))
    binary = float(Fraction(float(text)) * parse_unit(unit).exact_scale)
    event(f"the binary value would be off by an ulp: {binary != value}")
    assert value == float(exact)
    assert parse_unit(unit).from_si(value) == float(text)
