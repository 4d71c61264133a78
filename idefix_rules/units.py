"""Units and dimensions, shared by the rulebook language and campaign files.

Everything inside the project is SI (angles in radians, charge in A·s). A unit is a scale to SI
plus a :class:`Dimension`. Angles are a base dimension of their own, so ``5 cm + 2 deg`` is an
error while ``deg`` and ``rad`` convert exactly; ``%`` is the dimensionless ratio times 0.01.

>>> parse_quantity("70 %")
Quantity(value=0.7, dimension=Dimension())
>>> parse_unit("mAs").scale
0.001
>>> parse_unit("mm/s").dimension == parse_unit("m/s").dimension
True
"""

from __future__ import annotations

import functools
import math
import re
import unicodedata
from dataclasses import dataclass
from fractions import Fraction

_BASES = ("length", "mass", "time", "current", "angle")
_SYMBOLS = ("m", "kg", "s", "A", "rad")


@dataclass(frozen=True)
class Dimension:
    """Exponents of the base dimensions (length, mass, time, current, angle)."""

    length: int = 0
    mass: int = 0
    time: int = 0
    current: int = 0
    angle: int = 0

    def exponents(self) -> tuple[int, ...]:
        """Exponents in the order length, mass, time, current, angle."""
        return (self.length, self.mass, self.time, self.current, self.angle)

    def __mul__(self, other: Dimension) -> Dimension:
        return Dimension(*(a + b for a, b in zip(self.exponents(), other.exponents(), strict=True)))

    def __truediv__(self, other: Dimension) -> Dimension:
        return Dimension(*(a - b for a, b in zip(self.exponents(), other.exponents(), strict=True)))

    def __pow__(self, power: int) -> Dimension:
        return Dimension(*(a * power for a in self.exponents()))

    @property
    def is_dimensionless(self) -> bool:
        return not any(self.exponents())

    def __repr__(self) -> str:
        inner = ", ".join(f"{n}={e}" for n, e in zip(_BASES, self.exponents(), strict=True) if e)
        return f"Dimension({inner})"

    def __str__(self) -> str:
        """SI spelling, e.g. ``m/s``; ``1`` when dimensionless."""
        num = [_power(sym, e) for sym, e in zip(_SYMBOLS, self.exponents(), strict=True) if e > 0]
        den = [_power(sym, -e) for sym, e in zip(_SYMBOLS, self.exponents(), strict=True) if e < 0]
        text = "·".join(num) or "1"
        if den:
            text += "/" + ("·".join(den) if len(den) == 1 else "(" + "·".join(den) + ")")
        return text


def _power(symbol: str, exponent: int) -> str:
    return symbol if exponent == 1 else f"{symbol}^{exponent}"


DIMENSIONLESS = Dimension()
LENGTH = Dimension(length=1)
MASS = Dimension(mass=1)
TIME = Dimension(time=1)
CURRENT = Dimension(current=1)
ANGLE = Dimension(angle=1)
CHARGE = CURRENT * TIME
VELOCITY = LENGTH / TIME
ACCELERATION = VELOCITY / TIME
ANGULAR_RATE = ANGLE / TIME
FORCE = MASS * LENGTH / TIME**2
PRESSURE = FORCE / LENGTH**2

# Named dimensions, for messages like "expected an angle".
DIMENSION_NAMES: dict[Dimension, str] = {
    DIMENSIONLESS: "a ratio",
    LENGTH: "a length",
    MASS: "a mass",
    TIME: "a duration",
    CURRENT: "a current",
    ANGLE: "an angle",
    CHARGE: "a charge",
    VELOCITY: "a speed",
    ACCELERATION: "an acceleration",
    ANGULAR_RATE: "an angular rate",
    FORCE: "a force",
    PRESSURE: "a pressure",
}


def describe(dimension: Dimension) -> str:
    """Human name of a dimension: ``an angle``, or its SI unit when it has no name."""
    return DIMENSION_NAMES.get(dimension, f"a quantity in {dimension}")


@dataclass(frozen=True)
class Unit:
    """A unit: multiply a number in this unit by ``scale`` to get SI.

    The scale is kept as an exact fraction so decimal prefixes and ``%`` convert exactly
    (``70 %`` is the double nearest 0.7, ``648.32 mAs`` the double nearest 0.64832 A·s): the
    number is taken as the decimal it was written as (the shortest one its double reads back
    as), not as the double's binary value, which is off by up to half an ulp (7.4 is
    7.4000000000000003552…; times 1/100 it rounded to 0.07400000000000001, not 0.074).

    >>> parse_unit("cm").to_si(7.4), parse_unit("%").to_si(29.1), parse_unit("mm").to_si(74.0)
    (0.074, 0.291, 0.074)
    >>> parse_unit("cm").from_si(0.074)
    7.4
    """

    symbol: str
    exact_scale: Fraction
    dimension: Dimension

    @property
    def scale(self) -> float:
        return float(self.exact_scale)

    def to_si(self, number: float) -> float:
        return float(written_decimal(number) * self.exact_scale)

    def from_si(self, value: float) -> float:
        return float(written_decimal(value) / self.exact_scale)


def written_decimal(number: float) -> Fraction:
    """The decimal a double was written as: the shortest that reads back as it (``repr``).

    >>> written_decimal(0.1), written_decimal(7.4)
    (Fraction(1, 10), Fraction(37, 5))
    """
    if not math.isfinite(number):
        raise OverflowError(f"{number} has no exact value")
    return Fraction(repr(float(number)))


_DEG = Fraction(math.pi) / 180
_ATOMS: dict[str, tuple[Fraction, Dimension]] = {
    "1": (Fraction(1), DIMENSIONLESS),
    "%": (Fraction(1, 100), DIMENSIONLESS),
    "ratio": (Fraction(1), DIMENSIONLESS),
    "m": (Fraction(1), LENGTH),
    "cm": (Fraction(1, 100), LENGTH),
    "mm": (Fraction(1, 1000), LENGTH),
    "km": (Fraction(1000), LENGTH),
    "um": (Fraction(1, 10**6), LENGTH),
    "kg": (Fraction(1), MASS),
    "g": (Fraction(1, 1000), MASS),
    "s": (Fraction(1), TIME),
    "ms": (Fraction(1, 1000), TIME),
    "min": (Fraction(60), TIME),
    "h": (Fraction(3600), TIME),
    "A": (Fraction(1), CURRENT),
    "mA": (Fraction(1, 1000), CURRENT),
    "As": (Fraction(1), CHARGE),
    "mAs": (Fraction(1, 1000), CHARGE),
    "mAh": (Fraction(18, 5), CHARGE),
    "C": (Fraction(1), CHARGE),
    "rad": (Fraction(1), ANGLE),
    "mrad": (Fraction(1, 1000), ANGLE),
    "deg": (_DEG, ANGLE),
    "°": (_DEG, ANGLE),
    "rpm": (Fraction(math.pi) / 30, ANGULAR_RATE),
    "N": (Fraction(1), FORCE),
    "mN": (Fraction(1, 1000), FORCE),
    "Pa": (Fraction(1), PRESSURE),
    "kPa": (Fraction(1000), PRESSURE),
}
# Every unit atom the language knows (editor completion lists them).
UNIT_SYMBOLS: tuple[str, ...] = tuple(_ATOMS)

_TOKEN = re.compile(r"\s*([A-Za-z%°]+|1)(?:\^?(-?[0-9]+))?\s*")


class UnitError(ValueError):
    """A unit or quantity could not be understood; ``position`` is the index of the offending
    character in the text, where one is to blame."""

    def __init__(self, message: str, position: int | None = None) -> None:
        super().__init__(message)
        self.position = position


def foreign_digit(text: str) -> int | None:
    """Index of the first digit of ``text`` that is not one of 0-9 (``７``, ``٣`` …), if any.

    Python's ``float`` and ``\\d`` read every script's digits; numbers here are ASCII only, so
    that what is shown is what is read.

    >>> foreign_digit("７0 %")
    0
    """
    for index, char in enumerate(text):
        if not char.isascii() and unicodedata.decimal(char, None) is not None:
            return index
    return None


def foreign_digit_message(text: str, index: int) -> str:
    """``'７' (FULLWIDTH DIGIT SEVEN) is not one of the ASCII digits 0-9``."""
    char = text[index]
    return (f"'{char}' ({unicodedata.name(char, f'U+{ord(char):04X}')}) is not one of the "
            "ASCII digits 0-9")


def ascii_digits(text: str) -> str:
    """``text`` with every script's digits written 0-9 (for hints)."""
    return "".join(str(unicodedata.decimal(c)) if not c.isascii()
                   and unicodedata.decimal(c, None) is not None else c for c in text)


def underflows(number_text: str, value: float) -> bool:
    """Whether the literal ``number_text`` names a nonzero number that ``value`` (its double)
    holds as 0: ``1e-400``.

    >>> underflows("1e-400", float("1e-400")), underflows("0.0e-400", 0.0)
    (True, False)
    """
    mantissa = re.split("[eE]", number_text, maxsplit=1)[0]
    return value == 0 and any(char in "123456789" for char in mantissa)


PLAIN_NUMBER = re.compile(r"[-+]?(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][-+]?[0-9]+)?")
PLAIN_WHOLE_NUMBER = re.compile(r"[-+]?[0-9]+")


def plain_number(text: str) -> float:
    """``text`` (surrounding blanks aside) read as a plain ASCII decimal number: a sign,
    digits, a point, an exponent. Python's ``float`` also reads ``1_000``, every script's
    digits, ``nan`` and ``inf``, and a C reader of the same text (``%lf``) stops at the
    ``_``; a number read differently by two readers, or as 0 when it is not (``1e-400``), is
    refused with the reason (:class:`UnitError`). A number beyond a double is ``inf``: the
    caller says what range it wanted.

    >>> plain_number(" -2.5e3"), plain_number("1e400")
    (-2500.0, inf)
    >>> plain_number("1_000")
    Traceback (most recent call last):
    ...
    idefix_rules.units.UnitError: not a number: '1_000'
    """
    token = text.strip()
    foreign = foreign_digit(token)
    if foreign is not None:
        written = ascii_digits(token)  # a script's own decimal sign stays: then no advice
        advice = f": write {written!r}" if PLAIN_NUMBER.fullmatch(written) else ""
        raise UnitError(f"{foreign_digit_message(token, foreign)}{advice}", foreign)
    if PLAIN_NUMBER.fullmatch(token) is None:
        raise UnitError(f"not a number: {token!r}")
    value = float(token)
    if underflows(token, value):
        raise UnitError(f"{token.lstrip('+')} is too small for a double: it would be read as 0 "
                        "(write 0 if zero is meant)")
    return value


@functools.lru_cache(maxsize=1024)
def parse_unit(text: str) -> Unit:
    """Parse a unit expression: atoms joined by ``*``, ``·`` or ``/`` with ``^n`` powers.
    Units are immutable, so each text is parsed once (a report converts hundreds of values
    between the same few units).

    >>> parse_unit("m/s^2").dimension == ACCELERATION
    True
    >>> parse_unit("A·s").scale
    1.0
    """
    source = text.strip()
    if not source:
        raise UnitError("empty unit")
    foreign = foreign_digit(text)
    if foreign is not None:
        raise UnitError(f"{foreign_digit_message(text, foreign)} in unit {text!r}", foreign)
    scale = Fraction(1)
    dimension = DIMENSIONLESS
    sign = 1
    position = 0
    expect_atom = True
    while position < len(source):
        if expect_atom:
            match = _TOKEN.match(source, position)
            if match is None or match.group(1) not in _ATOMS:
                atom = match.group(1) if match else source[position:]
                where = "" if atom == source else f" in {text!r}"
                raise UnitError(f"unknown unit {atom!r}{where}")
            atom_scale, atom_dim = _ATOMS[match.group(1)]
            power = int(match.group(2)) if match.group(2) else 1
            scale *= atom_scale ** (sign * power)
            dimension = dimension * atom_dim ** (sign * power)
            position = match.end()
            expect_atom = False
        else:
            op = source[position]
            if op in "*·":
                sign = 1
            elif op == "/":
                sign = -1
            elif op.isspace():
                position += 1
                continue
            else:
                raise UnitError(f"unexpected {op!r} in unit {text!r}")
            position += 1
            expect_atom = True
    if expect_atom:
        raise UnitError(f"unit {text!r} ends with an operator")
    return Unit(source, scale, dimension)


@dataclass(frozen=True)
class Quantity:
    """A number in SI with its dimension."""

    value: float
    dimension: Dimension


_QUANTITY = re.compile(r"^\s*([-+]?(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][-+]?[0-9]+)?)\s*(.*?)\s*$")


def parse_quantity(text: str | float | int, default_unit: str | None = None) -> Quantity:
    """Parse ``"5 cm"`` → 0.05 m. A bare number takes ``default_unit`` (or is dimensionless).

    >>> parse_quantity("90 deg").value == math.pi / 2
    True
    """
    if isinstance(text, bool):
        raise UnitError(f"expected a quantity, got {text!r}")
    if isinstance(text, int | float):
        number, unit_text = float(text), ""
    else:
        foreign = foreign_digit(text)
        if foreign is not None:
            raise UnitError(f"{foreign_digit_message(text, foreign)}: write "
                            f"{ascii_digits(text).strip()!r}", foreign)
        match = _QUANTITY.match(text)
        if match is None:
            raise UnitError(f"expected a number with a unit, got {text!r}")
        number, unit_text = float(match.group(1)), match.group(2)
        if underflows(match.group(1), number):
            raise UnitError(f"{match.group(1).lstrip('+')} is too small for a double: it would "
                            "be read as 0 (write 0 if zero is meant)", match.start(1))
    if not unit_text:
        if default_unit is None:
            return Quantity(number, DIMENSIONLESS)
        unit_text = default_unit
    unit = parse_unit(unit_text)
    try:
        value = unit.to_si(number)
    except OverflowError:
        value = math.inf
    if not math.isfinite(value):
        raise UnitError(f"{text!r} is too large: in SI ({unit.dimension}) it is beyond a "
                        "double", 0)
    if value == 0 and number != 0:
        raise UnitError(f"{text!r} is too small for a double in SI: it would be read as 0 "
                        "(write 0 if zero is meant)", 0)
    return Quantity(value, unit.dimension)


def convert(value: float, from_unit: str, to_unit: str) -> float:
    """Convert between two units of the same dimension."""
    source, target = parse_unit(from_unit), parse_unit(to_unit)
    if source.dimension != target.dimension:
        raise UnitError(f"cannot convert {from_unit} ({describe(source.dimension)}) "
                        f"to {to_unit} ({describe(target.dimension)})")
    return float(Fraction(value) * source.exact_scale / target.exact_scale)


def percent_text(fraction: float) -> str:
    """A fraction in percent to three significant digits, with more where three would round
    a value below 100 % up to "100 %" (a confidence of 99.95 % is not "100 %").

    >>> [percent_text(f) for f in (0.95, 0.9875, 0.999, 0.9995, 0.99999, 1 - 0.05 / 3)]
    ['95 %', '98.8 %', '99.9 %', '99.95 %', '99.999 %', '98.3 %']
    """
    value = 100.0 * fraction
    for digits in range(3, 10):
        text = f"{value:.{digits}g}"
        if not (value < 100.0 <= float(text)):
            break
    return f"{text} %"
