"""YAML loading that remembers where every mapping key and sequence item came from.

Pydantic reports errors at a ``loc`` tuple such as ``("paths", "detour", 1, "delta_heading")``;
:class:`SourceMap` turns that back into ``campaign.yaml:12:5``. Only safe YAML is accepted.

>>> doc = load_yaml("a:\\n  - 1\\n  - x: 2\\n", "c.yaml")
>>> doc.data
{'a': [1, {'x': 2}]}
>>> str(doc.locations.span(("a", 1, "x")))
'c.yaml:3:8'
"""

from __future__ import annotations

import datetime
import re
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import yaml

from idefix_rules.errors import Diagnostic, Span, UserInputError, error
from idefix_rules.units import underflows

Loc = tuple[str | int, ...]

# Aliases let a few lines expand into billions of values ("billion laughs"); a campaign has a
# few hundred, so a document expanding past this is refused instead of exhausting memory.
MAX_VALUES = 100_000


@dataclass
class SourceMap:
    """Line and column of each node of a YAML document, keyed by its path in the data."""

    path: str
    values: dict[Loc, tuple[int, int]] = field(default_factory=dict)
    keys: dict[Loc, tuple[int, int]] = field(default_factory=dict)
    # a scalar YAML read as no text (a number, a boolean, a date, null) as it is written:
    # `0x10`, not 16, when a message quotes it
    written: dict[Loc, str] = field(default_factory=dict)

    def span(self, loc: Sequence[str | int], at_key: bool = False) -> Span:
        """Span of the deepest known prefix of ``loc`` (its key when ``at_key``)."""
        loc = tuple(loc)
        for end in range(len(loc), -1, -1):
            prefix = loc[:end]
            table = self.keys if at_key and end == len(loc) else self.values
            if prefix in table:
                line, column = table[prefix]
                return Span(self.path, line, column)
            if prefix in self.keys:
                line, column = self.keys[prefix]
                return Span(self.path, line, column)
        return Span(self.path)


@dataclass
class YamlDocument:
    data: Any
    locations: SourceMap
    text: str


_PLAIN_TAGS = ("tag:yaml.org,2002:map", "tag:yaml.org,2002:seq")


_MERGE = "tag:yaml.org,2002:merge"
_VALUE = "tag:yaml.org,2002:value"
_STR = "tag:yaml.org,2002:str"


class LocatingLoader(yaml.SafeLoader):  # type: ignore[misc]
    """A SafeLoader that records the position of every node while constructing the data."""

    values_seen = 0

    def __init__(self, stream: Any,
                 keys_as_written: Callable[[Loc], bool] = lambda loc: False) -> None:
        super().__init__(stream)
        self.keys_as_written = keys_as_written
        self._merging: set[int] = set()  # mappings whose merge keys are being resolved

    def flatten_mapping(self, node: yaml.MappingNode) -> None:
        """Resolve the merge key ``<<`` of a mapping (https://yaml.org/type/merge.html) in
        place: its value, a mapping or a list of mappings, gives the keys the mapping does not
        give itself, a mapping earlier in the list winning over a later one. The merged pairs
        stand where ``<<`` is written, their nodes those of the merged mapping (its lines).

        PyYAML's own puts every merged pair before the mapping's, so a key given both ways
        came twice: the campaign's duplicate check refused the override the merge key exists
        for. A key a mapping writes twice itself stays for that check, merged or not.
        """
        if id(node) in self._merging:
            raise yaml.constructor.ConstructorError(
                None, None, "a mapping merges itself: '<<' names the mapping it stands in",
                node.start_mark)
        merges = [pair for pair in node.value if pair[0].tag == _MERGE]
        for key_node, _ in node.value:
            if key_node.tag == _VALUE:  # `=`, YAML 1.1's default-value key: a plain name here
                key_node.tag = _STR
        if not merges:
            return
        if len(merges) > 1:
            raise yaml.constructor.ConstructorError(
                None, None, "a second merge key '<<' in one mapping: give one, with a list of "
                "the mappings to merge (<<: [*first, *second])", merges[1][0].start_mark)
        self._merging.add(id(node))
        try:
            given = {self._key_identity(key_node) for key_node, _ in node.value
                     if key_node.tag != _MERGE}
            merged = []
            for source in self._merge_sources(merges[0][1]):
                self.flatten_mapping(source)
                # a mapping's keys win over those of the mappings after it, and its own
                # duplicates are kept for the duplicate check
                own = [(self._key_identity(key_node), (key_node, value_node))
                       for key_node, value_node in source.value]
                merged += [pair for identity, pair in own if identity not in given]
                given |= {identity for identity, _ in own}
        finally:
            self._merging.discard(id(node))
        flat: list[tuple[yaml.Node, yaml.Node]] = []
        for pair in node.value:
            flat += merged if pair[0].tag == _MERGE else [pair]
        node.value = flat

    def _merge_sources(self, value_node: yaml.Node) -> list[yaml.MappingNode]:
        """The mappings a merge key's value names: itself, or the items of its list."""
        items = value_node.value if isinstance(value_node, yaml.SequenceNode) else [value_node]
        for item in items:
            if not isinstance(item, yaml.MappingNode):
                kind = ("a list" if isinstance(item, yaml.SequenceNode) else
                        f"{item.value}" if str(item.value).strip() else "nothing")
                raise yaml.constructor.ConstructorError(
                    None, None, f"a merge key '<<' takes a mapping (an alias such as *name of "
                    f"one) or a list of mappings, got {kind}", item.start_mark)
        return list(items)

    def _key_identity(self, key_node: yaml.Node) -> Any:
        """What makes two keys the same key: their values (``16`` and ``0x10`` are), their
        types apart (``true`` is not ``1``); a key that cannot be read is itself."""
        if isinstance(key_node, yaml.ScalarNode):
            try:
                key = self.construct_object(key_node, deep=True)
                hash(key)
            except (yaml.YAMLError, ValueError, TypeError, ArithmeticError, LookupError,
                    AttributeError):
                return ("node", id(key_node))
            return (type(key).__name__, key)
        return ("node", id(key_node))

    def construct_with_locations(self, node: yaml.Node, source_map: SourceMap,
                                 loc: Loc = ()) -> Any:
        self.values_seen += 1
        if self.values_seen > MAX_VALUES:
            raise UserInputError(error(
                "C003", f"the document expands to more than {MAX_VALUES} values",
                Span(source_map.path, node.start_mark.line + 1, node.start_mark.column + 1),
                hint="YAML aliases (*name) copy whole anchored blocks; nested ones multiply"))
        source_map.values[loc] = (node.start_mark.line + 1, node.start_mark.column + 1)
        if node.tag not in _PLAIN_TAGS and not isinstance(node, yaml.ScalarNode):
            # scalars' tags go through the safe constructor, which refuses unknown ones
            raise UserInputError(error(
                "C004", f"YAML tag {node.tag!r} is not allowed",
                Span(source_map.path, node.start_mark.line + 1, node.start_mark.column + 1)))
        if isinstance(node, yaml.MappingNode):
            self.flatten_mapping(node)
            result: dict[Any, Any] = {}
            for key_node, value_node in node.value:
                key: Any
                if isinstance(key_node, yaml.ScalarNode) and self.keys_as_written(loc):
                    key = str(key_node.value)  # a value for its reader to parse (a time)
                else:
                    key = (self._scalar(key_node, source_map)
                           if isinstance(key_node, yaml.ScalarNode) else None)
                if not isinstance(key, str):
                    raise UserInputError(_not_a_name(key_node, key, source_map.path))
                if key in result:
                    raise UserInputError(error(
                        "C002", f"duplicate key {key!r}",
                        Span(source_map.path, key_node.start_mark.line + 1,
                             key_node.start_mark.column + 1)))
                child = (*loc, key)
                source_map.keys[child] = (key_node.start_mark.line + 1,
                                          key_node.start_mark.column + 1)
                result[key] = self.construct_with_locations(value_node, source_map, child)
            return result
        if isinstance(node, yaml.SequenceNode):
            return [self.construct_with_locations(item, source_map, (*loc, index))
                    for index, item in enumerate(node.value)]
        value = self._scalar(node, source_map)
        if not isinstance(value, str):
            source_map.written[loc] = str(node.value)
        if isinstance(value, float) and underflows(str(node.value).replace("_", ""), value):
            # YAML reads `1.0e-400` as 0.0: refused here, where what was written is known
            where = "".join(f"[{part}]" if isinstance(part, int) else f".{part}"
                            for part in loc).lstrip(".")
            raise UserInputError(error(
                "C100", f"{where + ': ' if where else ''}{node.value} is too small for a "
                        "double: it would be read as 0",
                Span(source_map.path, node.start_mark.line + 1, node.start_mark.column + 1,
                     node.end_mark.line + 1, node.end_mark.column + 1),
                hint="write 0 if zero is meant"))
        return value


    def _scalar(self, node: yaml.Node, source_map: SourceMap) -> Any:
        """A scalar's value, or a diagnostic at it where the safe constructor refuses what the
        scalar's form or tag promises: a date that is no date (``2024-02-30``, resolved as a
        timestamp), ``!!int "abc"``, ``!!float "x"``, ``!!bool "maybe"``."""
        try:
            return self.construct_object(node, deep=True)
        except (ValueError, TypeError, ArithmeticError, LookupError, AttributeError) as failure:
            # (PyYAML's constructors raise these for a scalar they cannot read, a KeyError for
            # `!!bool maybe`, an AttributeError for `!!timestamp nope`)
            kind = str(node.tag).rsplit(":", 1)[-1]
            why = f" ({failure})" if isinstance(failure, ValueError | ArithmeticError) else ""
            raise UserInputError(error(
                "C000", f"invalid YAML: {node.value!r} is not a valid {kind}{why}",
                Span(source_map.path, node.start_mark.line + 1, node.start_mark.column + 1,
                     node.end_mark.line + 1, node.end_mark.column + 1),
                # where a date is meant (a waiver's until) quoting keeps it invalid
                hint=f"quote it to keep it as text (\"{node.value}\"), or write a valid "
                     + ("date or time if one is meant: a day and an hour that exist"
                        if kind == "timestamp" else kind))) from None



def _not_a_name(key_node: yaml.Node, key: Any, path: str) -> Diagnostic:
    """C001: a mapping key that is no name. Every key of a campaign or case file names
    something (a setting, a path, a parameter, an area), and a key YAML reads as a boolean,
    a number, a date or null would be taken for a list index (``paths[1]``) or be the same
    key as another written differently (``true`` and ``1``, ``0x10`` and ``16``): refused at
    the key, with its quoted form, which keeps it as written."""
    span = Span(path, key_node.start_mark.line + 1, key_node.start_mark.column + 1,
                key_node.end_mark.line + 1, key_node.end_mark.column + 1)
    if not isinstance(key_node, yaml.ScalarNode):
        kind = "a list" if isinstance(key_node, yaml.SequenceNode) else "a mapping"
        return error("C001", f"mapping keys must be plain names, not {kind}", span,
                     hint="write one key per line: `x: 1 cm`")
    written = str(key_node.value)
    if key is None and not written.strip():
        return error("C001", "a key is missing before ':'", span,
                     hint="write the name of what the value sets before the colon")
    quoted = '"' + written.replace("\\", "\\\\").replace('"', '\\"') + '"'
    return error("C001", f"the key {written} is read by YAML as {_kind_of(key)}, not as a name",
                 span, hint=f"quote it to keep it as a name: {quoted}")


def _kind_of(value: Any) -> str:
    """What YAML read a scalar as, in the words of the campaign docs."""
    if isinstance(value, bool):
        return "a boolean"
    if isinstance(value, int):
        return "a whole number"
    if isinstance(value, float):
        return "a number"
    if isinstance(value, datetime.datetime):
        return "a date and time"
    if isinstance(value, datetime.date):
        return "a date"
    if value is None:
        return "null (no value)"
    if isinstance(value, bytes):
        return "binary data"
    return "no text"


# Booleans as YAML 1.2 reads them: only true and false (any case). YAML 1.1, PyYAML's default,
# also reads yes/no/on/off/y/n unquoted as booleans, so a keep-out area named `off` or a path
# named `yes` became a boolean and was refused as "not a valid string". Where a flag is meant,
# pydantic still reads the text yes/no/on/off as one.
_BOOL = "tag:yaml.org,2002:bool"
LocatingLoader.yaml_implicit_resolvers = {
    first: [(tag, pattern) for tag, pattern in resolvers if tag != _BOOL]
    for first, resolvers in yaml.SafeLoader.yaml_implicit_resolvers.items()}
LocatingLoader.add_implicit_resolver(
    _BOOL, re.compile(r"^(?:true|True|TRUE|false|False|FALSE)$"), list("tTfF"))

# The words YAML 1.1 reads as booleans, which a flag still takes as written (the loader reads
# only true and false so).
FLAG_WORDS = {"true": True, "yes": True, "on": True, "y": True,
              "false": False, "no": False, "off": False, "n": False}


def flag_value(value: Any) -> Any:
    """A flag's value: a bool as given, one of :data:`FLAG_WORDS` written as text as its bool,
    anything else as given (for the caller to refuse)."""
    if isinstance(value, str) and value.lower() in FLAG_WORDS:
        return FLAG_WORDS[value.lower()]
    return value


def yaml_data(text: str) -> Any:
    """The data of YAML text as :func:`load_yaml` reads it (safely, booleans as YAML 1.2 reads
    them), without positions or checks: for readers of a campaign already checked (a stored
    one, its units). PyYAML's errors propagate."""
    return yaml.load(text, Loader=LocatingLoader)


def load_yaml(text: str, path: str,
              keys_as_written: Callable[[Loc], bool] = lambda loc: False) -> YamlDocument:
    """Parse YAML text safely, with a :class:`SourceMap`; syntax errors become diagnostics.

    Every mapping key is a name, text (C001 for one YAML reads as a boolean, a number, a date
    or null), except in the mappings at the locations ``keys_as_written`` accepts, whose keys
    are values their reader parses (a case file's keyframe times): taken as written."""
    loader = LocatingLoader(text, keys_as_written)
    source_map = SourceMap(path)
    try:
        node = loader.get_single_node()
        data = None if node is None else loader.construct_with_locations(node, source_map)
    except yaml.MarkedYAMLError as failure:
        mark = failure.problem_mark or failure.context_mark
        span = Span(path, mark.line + 1, mark.column + 1) if mark else Span(path)
        message = failure.problem or str(failure)
        raise UserInputError(error("C000", f"invalid YAML: {message}", span),
                             sources={path: text}) from None
    except yaml.YAMLError as failure:
        raise UserInputError(error("C000", f"invalid YAML: {failure}", Span(path)),
                             sources={path: text}) from None
    except RecursionError:
        mark = loader.get_mark()
        raise UserInputError(error("C000", "invalid YAML: nested too deeply",
                                   Span(path, mark.line + 1, mark.column + 1)),
                             sources={path: text}) from None
    finally:
        loader.dispose()
    return YamlDocument(data, source_map, text)


def format_loc(loc: Sequence[str | int]) -> str:
    """``("paths", "detour", 1, "delta_heading")`` → ``paths.detour[1].delta_heading``."""
    text = ""
    for part in loc:
        if isinstance(part, int):
            text += f"[{part}]"
        else:
            text += ("." if text else "") + str(part)
    return text
