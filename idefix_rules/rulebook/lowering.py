"""The lark tree lowered into the rule model's frozen nodes, each with its span."""

from __future__ import annotations

import dataclasses
import math
import re
from collections.abc import Sequence
from typing import Any

from lark import Token, Transformer, v_args

from idefix_rules.errors import Diagnostic, Span, error
from idefix_rules.rulebook import model
from idefix_rules.rulebook.infer import did_you_mean
from idefix_rules.units import underflows

NUMBER_OUT_OF_RANGE = "E003"
INDEX_ITEM = "E006"
UNKNOWN_DOMAIN = "E007"
UNKNOWN_COMBINATION = "E008"

RUN_COMBINATIONS = ("max_weighted",)
PATH_COMBINATIONS = ("mean",)

_QUANTITY = re.compile(r"((?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][-+]?[0-9]+)?)[ \t]*(.*)",
                       re.DOTALL)


def meta_span(path: str, meta: Any) -> Span:
    """The span of a node from lark's ``meta`` (``NO_SPAN`` when lark gives none)."""
    if getattr(meta, "empty", True):
        return model.NO_SPAN
    return Span(path, meta.line, meta.column, meta.end_line, meta.end_column)


def _token_span(path: str, token: Token) -> Span:
    return Span(path, token.line or 0, token.column or 0, token.end_line or 0,
                token.end_column or 0)


def _unquote(token: Token) -> str:
    body = str(token)[1:-1]
    return re.sub(r'\\(["\\])', r"\1", body)


@dataclasses.dataclass
class _Item:
    """An item of a block (``limit = …``, ``because "…"``) before it lands in its node."""

    key: str
    value: Any
    span: Span


@dataclasses.dataclass
class Section:
    """A ``settings``/``obstacles``/``combine`` block: its entries and where it is."""

    kind: str
    entries: list[Any]
    span: Span


@v_args(meta=True)
class Lowering(Transformer):  # type: ignore[type-arg]
    """Lark tree → model nodes. Structure problems are collected in ``diagnostics``."""

    def __init__(self, path: str) -> None:
        super().__init__()
        self.path = path
        self.diagnostics: list[Diagnostic] = []

    def _s(self, meta: Any) -> Span:
        return meta_span(self.path, meta)

    # ---- expressions

    def number(self, meta: Any, children: list[Token]) -> model.Number | model.Invalid:
        token = children[0]
        match = _QUANTITY.fullmatch(str(token))
        number_text, unit = (match.group(1), match.group(2)) if match else (str(token), "")
        value = float(number_text)
        span = _token_span(self.path, token)
        if not math.isfinite(value):
            self.diagnostics.append(error(NUMBER_OUT_OF_RANGE, f"number {number_text} is too "
                                          "large", span))
            return model.Invalid(span=span)
        if underflows(number_text, value):
            self.diagnostics.append(error(
                NUMBER_OUT_OF_RANGE, f"number {str(token).strip()} is too small for a double: "
                                     "it would be read as 0", span,
                hint="write 0 if zero is meant, or a realistic value"))
            return model.Invalid(span=span)
        return model.Number(value, unit or None, span=span)

    def name(self, meta: Any, children: list[Token]) -> model.Name:
        return model.Name(str(children[0]), span=_token_span(self.path, children[0]))

    def binary(self, meta: Any, children: list[Any]) -> model.Binary:
        left, operator, right = children
        return model.Binary(str(operator), left, right, span=self._s(meta))  # type: ignore[arg-type]

    def unary(self, meta: Any, children: list[Any]) -> model.Unary:
        operator, operand = children
        return model.Unary(str(operator), operand, span=self._s(meta))  # type: ignore[arg-type]

    def select(self, meta: Any, children: list[Any]) -> model.Select:
        operand, *labels = children
        return model.Select(operand, tuple(str(label) for label in labels), span=self._s(meta))

    def callee(self, meta: Any, children: list[Token]) -> str:
        return str(children[0])

    def arguments(self, meta: Any, children: list[Any]) -> tuple[Any, ...]:
        return tuple(children)

    def call(self, meta: Any, children: list[Any]) -> model.Call:
        function, arguments = children
        return model.Call(function, arguments or (), span=self._s(meta))

    def table_entry(self, meta: Any, children: list[Any]) -> tuple[str, Any]:
        return str(children[0]), children[1]

    def table_entries(self, meta: Any, children: list[Any]) -> tuple[Any, ...]:
        return tuple(child for child in children if child is not None)

    def table(self, meta: Any, children: list[Any]) -> model.Table:
        return model.Table(children[0] or (), span=self._s(meta))

    def reducer(self, meta: Any, children: list[Token]) -> str:
        return str(children[0])

    param_reducer = reducer

    def parameter(self, meta: Any, children: list[Any]) -> Any:
        return children[0]

    def reduction(self, meta: Any, children: list[Any]) -> model.Reduce | model.Invalid:
        if len(children) == 4:
            reducer, domain, window, operand = children
            parameter = None
        else:
            reducer, parameter, domain, window, operand = children
        domain_text = str(domain)
        reduce = model.Reduce(reducer, domain_text, operand, parameter,  # type: ignore[arg-type]
                              window, span=self._s(meta))
        if domain_text not in model.DOMAIN_AXES:
            known = list(model.DOMAIN_AXES)
            hint = did_you_mean(domain_text, known)
            self.diagnostics.append(error(
                UNKNOWN_DOMAIN, f"unknown domain '{domain_text}' after 'over'; "
                f"expected {', '.join(known[:-1])} or {known[-1]}",
                _token_span(self.path, domain), hint))
            return model.Invalid(reduce, span=reduce.span)
        return reduce

    def during_command(self, meta: Any, children: list[Any]) -> model.Window:
        return model.Window("command", children[0], span=self._s(meta))

    def after(self, meta: Any, children: list[Any]) -> model.Window:
        return model.Window("after", children[0], span=self._s(meta))

    def before(self, meta: Any, children: list[Any]) -> model.Window:
        return model.Window("before", children[0], span=self._s(meta))

    # ---- declarations

    def rationale(self, meta: Any, children: list[Token]) -> _Item:
        return _Item("because", _unquote(children[0]), self._s(meta))

    @staticmethod
    def _because(item: _Item | None) -> str | None:
        return item.value if item is not None else None

    def header(self, meta: Any, children: list[Token]) -> model.Header:
        name, version, purpose = (_unquote(child) for child in children)
        name_span, version_span, purpose_span = (_token_span(self.path, child)
                                                 for child in children)
        return model.Header(name, version, purpose, span=self._s(meta), name_span=name_span,
                            version_span=version_span, purpose_span=purpose_span)

    def constant(self, meta: Any, children: list[Any]) -> model.Constant:
        name, value, because = children
        return model.Constant(str(name), value, self._because(because), span=self._s(meta))

    def setting(self, meta: Any, children: list[Any]) -> model.Setting:
        return model.Setting(str(children[0]), children[1], span=self._s(meta))

    def settings(self, meta: Any, children: list[Any]) -> Section:
        return Section("settings", children, self._s(meta))

    def level(self, meta: Any, children: list[Any]) -> model.ObstacleLevel:
        name, below, buffer = children
        return model.ObstacleLevel(str(name), below, buffer, span=self._s(meta))

    def keep_out(self, meta: Any, children: list[Any]) -> tuple[str, None]:
        return ("keep_out", None)

    def unknown_surface(self, meta: Any, children: list[Any]) -> tuple[str, None]:
        return ("unknown", None)

    def steep(self, meta: Any, children: list[Any]) -> tuple[str, Any]:
        return ("steep", children[0])

    def area(self, meta: Any, children: list[Any]) -> model.Area:
        name, (kind, above), level, buffer, because = children
        return model.Area(str(name), kind, str(level), buffer, above, self._because(because),
                          span=self._s(meta))

    def obstacles(self, meta: Any, children: list[Any]) -> Section:
        return Section("obstacles", children, self._s(meta))

    def command_rule(self, meta: Any, children: list[Any]) -> model.CommandRule:
        name, condition, because = children
        return model.CommandRule(str(name), condition, self._because(because),
                                 span=self._s(meta))

    def prescreen(self, meta: Any, children: list[Any]) -> model.Prescreen:
        name, condition, because = children
        return model.Prescreen(str(name), condition, self._because(because), span=self._s(meta))

    def verdict(self, meta: Any, children: list[Any]) -> model.VerdictRule:
        name, condition, margin, because = children
        return model.VerdictRule(str(name), condition, self._because(because),
                                 span=self._s(meta), indifference=margin)

    def verdict_margin(self, meta: Any, children: list[Any]) -> Any:
        return children[0]

    def chance(self, meta: Any, children: list[Any]) -> model.Chance:
        name, condition, because = children
        return model.Chance(str(name), condition, self._because(because), span=self._s(meta))

    def index_value(self, meta: Any, children: list[Any]) -> _Item:
        return _Item("value", children[0], self._s(meta))

    def index_nominal(self, meta: Any, children: list[Any]) -> _Item:
        return _Item("nominal", children[0], self._s(meta))

    def index_limit(self, meta: Any, children: list[Any]) -> _Item:
        return _Item("limit", children[0], self._s(meta))

    def index_weight(self, meta: Any, children: list[Any]) -> _Item:
        return _Item("weight", children[0], self._s(meta))

    def index_map(self, meta: Any, children: list[Any]) -> _Item:
        return _Item("map", children[0], self._s(meta))

    def _items(self, owner: str, items: Sequence[_Item]) -> dict[str, _Item]:
        found: dict[str, _Item] = {}
        for item in items:
            if item.key in found:
                self.diagnostics.append(error(
                    INDEX_ITEM, f"{owner} gives '{item.key}' twice", item.span,
                    f"the first is on line {found[item.key].span.line}"))
            else:
                found[item.key] = item
        return found

    def index(self, meta: Any, children: list[Any]) -> model.Index:
        name, title, *items = children
        span = self._s(meta)
        found = self._items(f"index '{name}'", items)
        name_span = _token_span(self.path, name)
        for key in ("value", "limit", "weight"):
            if key not in found:
                self.diagnostics.append(error(
                    INDEX_ITEM, f"index '{name}' has no '{key}'", name_span,
                    f"add `{key} = …` inside the braces"))

        def get(key: str) -> Any:
            return found[key].value if key in found else None

        def required(key: str) -> Any:  # a missing item: no type, its E006 says why
            return found[key].value if key in found else model.Invalid(span=name_span)

        return model.Index(
            str(name), required("value"), required("limit"), required("weight"),
            _unquote(title) if title is not None else None,
            get("map"), get("because"), get("nominal"), span=span)

    def combine_method(self, meta: Any, children: list[Token]) -> Token:
        return children[0]

    def combine_run(self, meta: Any, children: list[Any]) -> _Item:
        return self._method("run", children[0], RUN_COMBINATIONS, meta)

    def combine_path(self, meta: Any, children: list[Any]) -> _Item:
        return self._method("path", children[0], PATH_COMBINATIONS, meta)

    def _method(self, key: str, token: Token, known: tuple[str, ...], meta: Any) -> _Item:
        if str(token) not in known:
            self.diagnostics.append(error(
                UNKNOWN_COMBINATION, f"unknown {key} combination '{token}'; the language knows "
                + ", ".join(known), _token_span(self.path, token)))
        return _Item(key, str(token), self._s(meta))

    def combine_confidence(self, meta: Any, children: list[Any]) -> _Item:
        return _Item("confidence", children[0], self._s(meta))

    def combine_indifference(self, meta: Any, children: list[Any]) -> _Item:
        return _Item("indifference", children[0], self._s(meta))

    def combine_verdict_indifference(self, meta: Any, children: list[Any]) -> _Item:
        return _Item("verdict_indifference", children[0], self._s(meta))

    def combine(self, meta: Any, children: list[_Item]) -> model.Combine:
        found = self._items("combine", children)
        run = found["run"].value if "run" in found else "max_weighted"
        path = found["path"].value if "path" in found else "mean"
        confidence = found["confidence"].value if "confidence" in found else None
        indifference = found["indifference"].value if "indifference" in found else None
        verdicts = (found["verdict_indifference"].value if "verdict_indifference" in found
                    else None)
        return model.Combine(run, path, confidence, indifference,  # type: ignore[arg-type]
                             verdicts, span=self._s(meta))

    def rank_key(self, meta: Any, children: list[Any]) -> model.RankKey:
        expr, descending = children
        return model.RankKey(expr, descending is not None, span=self._s(meta))

    def ranking(self, meta: Any, children: list[model.RankKey]) -> model.Ranking:
        return model.Ranking(tuple(children), span=self._s(meta))

    def start(self, meta: Any, children: list[Any]) -> list[Any]:
        return children
