"""pydantic's errors on a campaign file as diagnostics in the campaign's words and lines."""

from __future__ import annotations

import difflib
import typing
from collections.abc import Sequence
from typing import Any

import yaml
from pydantic import BaseModel, ValidationError

from idefix_rules.campaign.input.distributions import Distribution
from idefix_rules.campaign.input.expectations import EXPECTATION_KINDS
from idefix_rules.campaign.input.schema import CampaignFile
from idefix_rules.campaign.input.yamlsource import SourceMap, format_loc
from idefix_rules.errors import Diagnostic, Span, error


def _data_loc(data: Any, loc: Sequence[str | int]) -> tuple[tuple[str | int, ...], bool]:
    """Keep only the parts of a pydantic ``loc`` that exist in the data (drops union tags).

    Returns the cleaned location and whether its last part exists in the data. A union tag
    may also be a key of the data (an expectation's ``verdict`` is its tag and its key), so
    a tag is read both ways: as the key where only that reading finds the location in the
    data, as the tag otherwise (pydantic puts the tag before every location in a member).

    >>> entry = {"path": "p", "verdict": "fail", "rank": 1}
    >>> _data_loc({"expect": [entry]}, ("expect", 0, "verdict", "rank"))
    (('expect', 0, 'rank'), True)
    >>> _data_loc({"expect": [entry]}, ("expect", 0, "verdict", "verdict"))
    (('expect', 0, 'verdict'), True)
    """
    found, _, cleaned = _read_loc(data, tuple(loc))
    return cleaned, found


def _read_loc(node: Any, loc: tuple[str | int, ...]) -> tuple[bool, bool, tuple[str | int, ...]]:
    """For :func:`_data_loc`: whether all of ``loc`` was found in ``node``, whether the
    reading fits the data (it looks for no key inside a plain value), and the parts kept."""
    if not loc:
        return True, True, ()
    part, rest = loc[0], loc[1:]
    if part == "[key]":  # pydantic's marker for a mapping's key: the key before it
        return True, True, ()
    in_dict = isinstance(node, dict) and part in node
    in_list = isinstance(node, list) and isinstance(part, int) and 0 <= part < len(node)
    if in_dict or in_list:
        found, fits, cleaned = _read_loc(node[part], rest)
        as_data = (found, fits, (part, *cleaned))
        if part in _UNION_TAGS and isinstance(node, dict) and rest:
            as_tag = _read_loc(node, rest)
            # the tag reading wins when it reads more of the location, or on a tie where
            # neither reading finds the key (a kind's key missing from its entry)
            if as_tag[:2] > as_data[:2] or (as_tag[:2] == as_data[:2] and not as_tag[0]):
                return as_tag
        return as_data
    if not isinstance(node, dict | list):
        return False, False, ()
    if isinstance(part, str) and part.isidentifier() and part not in _UNION_TAGS:
        return False, True, (part,)  # a missing key: kept for the message
    # a union tag ("normal") or another marker of pydantic's: not in the data
    return _read_loc(node, rest) if rest else (False, True, ())


_UNION_TAGS = frozenset({"fixed", "normal", "truncated_normal", "uniform", "log_normal",
                         "verdict", "rank_first", "max_mean_risk", "max_collision_chance"})


def _inside_value(span: Span, value: str, position: int, text: str) -> Span:
    """The span of character ``position`` of the string ``value`` written at ``span`` (the
    value's own span when it is not written there as such, e.g. with escapes)."""
    lines = text.splitlines()
    if not 0 < span.line <= len(lines):
        return span
    found = lines[span.line - 1].find(value, max(span.column - 1, 0))
    if found < 0 or found > span.column + 1:  # the value, after at most a quote
        return span
    column = found + position + 1
    return Span(span.path, span.line, column, span.line, column + 1)


def diagnostics_from_validation(failure: ValidationError, data: Any,
                                locations: SourceMap, text: str) -> list[Diagnostic]:
    diagnostics = []
    seen = set()
    errors = failure.errors(include_url=False)
    for item in errors:
        loc, found = _data_loc(data, item["loc"])
        kind = item["type"]
        hint = None
        if kind == "extra_forbidden":
            message = "unknown key"
            span = locations.span(loc, at_key=True)
            hint = _did_you_mean(loc, data)
        elif kind == "missing" and item["loc"] and isinstance(item["loc"][-1], int) \
                and isinstance(item.get("input"), list):
            # a list too short for its tuple (semi_axes of two values): pydantic reports each
            # item it lacks as a missing key
            wanted = 1 + max(other["loc"][-1] for other in errors
                             if other["type"] == "missing" and other["loc"][:-1] == item["loc"][:-1]
                             and isinstance(other["loc"][-1], int))
            got = len(item["input"])
            message = f"expected {wanted} values, got {got}"
            loc, _ = _data_loc(data, item["loc"][:-1])  # the list itself
            span = locations.span(loc)
        elif kind == "missing":
            message = "missing required key"
            span = locations.span(loc[:-1] if not found else loc)
        elif kind in _BOUND_WORDS:  # pydantic's "Input should be greater than 0"
            bound = next(iter(item.get("ctx", {}).values()), "")
            message = f"must be {_BOUND_WORDS[kind]} {bound}"
            span = locations.span(loc)
        elif kind in ("too_long", "too_short"):  # "Tuple should have at most 2 items …"
            context = item.get("ctx", {})
            limit = context.get("max_length" if kind == "too_long" else "min_length")
            message = (f"expected {'at most' if kind == 'too_long' else 'at least'} {limit} "
                       f"value{'' if limit == 1 else 's'}, got {context.get('actual_length')}")
            span = locations.span(loc)
        elif kind == "literal_error":  # "Input should be 'monte_carlo', … or 'sobol'"
            expected = item.get("ctx", {}).get("expected", "")
            message = f"expected {expected}, got {_shown(item.get('input'))}"
            span = locations.span(loc, at_key=item["loc"][-1:] == ("[key]",))
        elif kind in ("model_type", "model_attributes_type", "dict_type"):
            # pydantic's words name its classes ("instance of TerrainSection"): not the user's
            message = f"expected a mapping (key: value), got {_shown(item.get('input'))}"
            span = locations.span(loc)
        elif kind == "union_tag_invalid":
            context = item.get("ctx", {})
            name = str(context.get("discriminator", "kind")).strip(chr(39))
            # as written: `true`, not pydantic's 'True'
            tag = locations.written.get((*loc, name), context.get("tag"))
            message = (f"unknown {name} {tag!r} (expected one of: "
                       f"{context.get('expected_tags', '')})")
            span = locations.span((*loc, "distribution"))
        elif kind in _EXPECTED or kind == "union_tag_not_found":
            # pydantic's "Input should be a valid list": what is expected, with an example
            message, hint = _type_error(kind, item, loc, locations)
            span = locations.span(loc)
            if kind == "union_tag_not_found":  # the key that says which kind is missing
                loc = (*loc, _discriminator(item))
        elif kind == "expectation" and isinstance(item.get("input"), dict):
            # an entry of no kind: its keys the schema does not know are likely the kind
            # misspelt (`rank: 1` for `rank_first`)
            message = str(item["msg"])
            span = locations.span(loc)
            extra = [(*loc, key) for key in item["input"] if key not in _ALL_EXPECTATION_KEYS]
            for key_loc in extra:
                diagnostics.append(error("C100", f"{format_loc(key_loc)}: unknown key",
                                         locations.span(key_loc, at_key=True),
                                         _did_you_mean(key_loc, data)))
        else:
            # a validator's own words, without pydantic's "Value error, " before them
            message = str(item["msg"]).removeprefix("Value error, ")
            # "[key]": pydantic's marker for a mistake in a mapping key, not its value
            span = locations.span(loc, at_key=item["loc"][-1:] == ("[key]",))
            position = item.get("ctx", {}).get("position")
            if isinstance(position, int) and isinstance(item.get("input"), str):
                span = _inside_value(span, item["input"], position, text)
        where = format_loc(loc)
        text = f"{where}: {message}" if where else message
        if (text, str(span)) in seen:
            continue
        seen.add((text, str(span)))
        diagnostics.append(error("C100", text, span, hint))
    diagnostics.sort(key=lambda d: (d.span.line, d.span.column) if d.span else (0, 0))
    return diagnostics


def _shown(value: Any, written: str | None = None) -> str:
    """A value as the campaign file wrote it (a string in quotes, a number as it is, as
    ``written`` where the file's text of it is known: ``0x10``, not 16)."""
    if isinstance(value, str):
        return f"'{value}'"
    if value is None and not (written or "").strip():
        return "nothing"
    if written is not None:
        return written
    if isinstance(value, list | dict):  # in YAML's flow style: [a, 2027-03-31], not a repr
        text = str(yaml.safe_dump(value, default_flow_style=True, width=1000)).strip()
        return text if len(text) <= 60 else text[:59] + "…"
    return str(value).lower() if isinstance(value, bool) else str(value)


# What each of pydantic's type errors that a campaign file can meet expects, in the words of
# the other messages (pydantic's own: "Input should be a valid list", "Unable to extract tag
# using discriminator 'distribution'", "Datetimes provided to dates should have zero time").
_EXPECTED = {
    "string_type": "text",
    "int_type": "a whole number",
    "int_parsing": "a whole number",
    "int_from_float": "a whole number",
    "float_type": "a number",
    "float_parsing": "a number",
    "bool_type": "a boolean: true or false (or yes/no, on/off)",
    "bool_parsing": "a boolean: true or false (or yes/no, on/off)",
    "list_type": "a list",
    "tuple_type": "a list",
    "date_type": "a date written YYYY-MM-DD",
    "date_parsing": "a date written YYYY-MM-DD",
    "date_from_datetime_parsing": "a date written YYYY-MM-DD",
    "date_from_datetime_inexact": "a date without a time of day",
}

_POINT = '["1 m", "0 m"] (x, y)'
_POLYGON = '[["1 m", "0 m"], ["1.2 m", "0 m"], ["1.2 m", "0.2 m"]]'
_COMMAND = '{max_wheel_rate: "0.05 rad/s", delta_position: "1 m", delta_heading: "0 deg"}'

# (the field, how many list levels below it) -> an example of what it takes
_EXAMPLES: dict[tuple[str, int], str] = {
    ("paths", 1): f"[{_COMMAND}], or one command per '- ' line",
    ("expect", 0): "expect: [{path: straight, verdict: pass}], or expect: [] for none",
    ("waivers", 0): 'waivers: [{rule: max_turn, path: detour, reason: "…", approved_by: '
                    "NAME, until: 2027-03-31}], or waivers: [] for none",
    ("rocks", 0): 'rocks: [{x: "0.5 m", y: "0 m", radius: "5 cm"}], or rocks: [] for none',
    ("keep_out", 0): f"keep_out: [{{name: ridge, polygon: {_POLYGON}}}], or keep_out: [] for "
                     "none",
    ("polygons", 0): f"polygons: [{_POLYGON}], or polygons: [] for none",
    ("polygons", 1): _POLYGON,
    ("polygons", 2): _POINT,
    ("polygon", 0): f"polygon: {_POLYGON}",
    ("polygon", 1): _POINT,
    ("origin", 0): 'origin: ["-2 m", "-2 m"] (x, y)',
    ("semi_axes", 0): 'semi_axes: ["5 cm", "5 cm", "3 cm"]',
    ("seed", 0): "seed: 3",
    ("max_runs", 0): "max_runs: 1000",
    ("min_runs", 0): "min_runs: 32",
    ("batch_runs", 0): "batch_runs: 32",
    ("done_at", 0): "done_at: 1",
    ("until", 0): "until: 2027-03-31",
    ("paired", 0): "paired: false",
    ("command_rules", 0): "command_rules: true",
}
# the values a tuple takes: (the field, list levels below it) -> how many
_TUPLE_SIZES = {("origin", 0): 2, ("semi_axes", 0): 3, ("polygon", 1): 2, ("polygons", 2): 2}


def _field(loc: Sequence[str | int]) -> tuple[str, int]:
    """The field a location is in and how many list levels below it: ``("environment",
    "keep_out", 0, "polygon", 2)`` → ``("polygon", 1)``; a path's chain is ``("paths", 1)``."""
    if len(loc) == 2 and loc[0] == "paths":
        return "paths", 1
    names = [index for index, part in enumerate(loc) if isinstance(part, str)]
    if not names:
        return "", len(loc)
    return str(loc[names[-1]]), len(loc) - 1 - names[-1]


def _type_error(kind: str, item: Any, loc: Sequence[str | int],
                locations: SourceMap) -> tuple[str, str | None]:
    """The message and hint of one of pydantic's type errors (:data:`_EXPECTED`)."""
    value = item.get("input")
    got = _shown(value, locations.written.get(tuple(loc)))
    where = _field(loc)
    example = _EXAMPLES.get(where)
    hint = f"for example {example}" if example else None
    if kind == "union_tag_not_found":
        return (f"missing required key: which distribution, one of {_DISTRIBUTIONS}",
                'for example {distribution: normal, mean: "0 m", std: "1 cm"}')
    expected = _EXPECTED[kind]
    if kind == "tuple_type" and where in _TUPLE_SIZES:
        expected = f"a list of {_TUPLE_SIZES[where]} values"
    if kind == "string_type" and value is not None and not isinstance(value, list | dict):
        # a name or a text YAML read as a number, a boolean or a date
        written = got.replace("\\", "\\\\").replace('"', '\\"')
        hint = f'quote it to keep it as text: "{written}"'
    if kind == "date_from_datetime_inexact":
        return (f"expected a date without a time of day, got {got} (a waiver holds up to and "
                "including the day it names)", hint)
    return f"expected {expected}, got {got}", hint


def _discriminator(item: Any) -> str:
    return str(item.get("ctx", {}).get("discriminator", "distribution")).strip("'")


def _distribution_kinds() -> str:
    """The distributions a parameter may take: 'fixed', 'normal', … or 'log_normal'."""
    union = typing.get_args(Distribution)[0]
    kinds = [f"'{typing.get_args(model.model_fields['distribution'].annotation)[0]}'"
             for model in typing.get_args(union)]
    return ", ".join(kinds[:-1]) + f" or {kinds[-1]}"


_DISTRIBUTIONS = _distribution_kinds()


# pydantic's bound checks in the words of the other messages
_BOUND_WORDS = {"greater_than": "above", "greater_than_equal": "at least",
                "less_than": "below", "less_than_equal": "at most"}


def _did_you_mean(loc: Sequence[str | int], data: Any) -> str | None:
    """The hint for the unknown key ending ``loc``: the known key closest to it, if any is
    close (a misspelling, or the start of a longer key: ``rank`` for ``rank_first``)."""
    if not loc:
        return None
    written, known = str(loc[-1]), _known_keys(loc, data)
    close = difflib.get_close_matches(written, known, n=1) or [
        key for key in known if len(written) >= 3 and key.startswith(written)][:1]
    return f"did you mean '{close[0]}'?" if close else None


def _known_keys(loc: Sequence[str | int], data: Any) -> list[str]:
    """The keys the campaign schema knows where ``loc``'s last key stands (a section that is
    a model of its own, or an expectation: those of its kind, all kinds' for an entry of no
    kind; none where the schema says less)."""
    if len(loc) == 3 and loc[0] == "expect" and isinstance(loc[1], int):
        expect = data.get("expect") if isinstance(data, dict) else None
        entry = expect[loc[1]] if isinstance(expect, list) and 0 <= loc[1] < len(expect) \
            else None
        kinds = [model for kind, model in EXPECTATION_KINDS.items()
                 if isinstance(entry, dict) and kind in entry]
        return _field_names(*kinds) if kinds else list(_ALL_EXPECTATION_KEYS)
    model: Any = CampaignFile
    for part in loc[:-1]:
        field = model.model_fields.get(part) if isinstance(part, str) else None
        annotation = getattr(field, "annotation", None)
        if not (isinstance(annotation, type) and issubclass(annotation, BaseModel)):
            return []
        model = annotation
    return _field_names(model)


def _field_names(*models: type[BaseModel]) -> list[str]:
    return list(dict.fromkeys(field.alias or name for model in models
                              for name, field in model.model_fields.items()))


_ALL_EXPECTATION_KEYS = _field_names(*EXPECTATION_KINDS.values())
