"""pydantic's errors on a campaign file as diagnostics in the campaign's words and lines."""

from __future__ import annotations

import difflib
from collections.abc import Sequence
from typing import Any

from pydantic import BaseModel, ValidationError

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
            message = (f"unknown {context.get('discriminator', 'kind').strip(chr(39))} "
                       f"{context.get('tag')!r} (expected one of: "
                       f"{context.get('expected_tags', '')})")
            span = locations.span((*loc, "distribution"))
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


def _shown(value: Any) -> str:
    """A value as the campaign file wrote it (a string in quotes, a number as it is)."""
    return f"'{value}'" if isinstance(value, str) else str(value)


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
