"""The campaign waivers a rulebook change touches: ``idefix-verify diff OLD NEW --waivers
CAMPAIGN.yaml``. A waiver was approved for a rule as it was; when that rule changed, was
removed, or reads something that changed, the approval wants a second look.

>>> from types import SimpleNamespace as S
>>> change = S(section="verdict", name="acceptable_risk", kind="changed")
>>> waiver = S(rule="acceptable_risk", path="all", approved_by="J. Doe", until="2026-12-01")
>>> [w.to_dict()["change"] for w in touched_waivers([change], [waiver])]
['changed']
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import Any

WAIVABLE_SECTIONS = frozenset({"command", "prescreen", "verdict"})


@dataclass(frozen=True)
class TouchedWaiver:
    """A waiver of the campaign (``waivers[number]``) whose rule the change touches."""

    number: int
    rule: str
    path: str
    approved_by: str
    until: str
    change: str  # changed, removed or affected

    def to_dict(self) -> dict[str, Any]:
        return dict(self.__dict__)

    def text(self) -> str:
        return (f"waivers[{self.number}] ({self.rule} on {self.path}, approved by "
                f"{self.approved_by} until {self.until}): the rule is {self.change}")


def touched_waivers(changes: Iterable[Any], waivers: Sequence[Any]) -> list[TouchedWaiver]:
    """The waivers whose rule a rule diff's ``changes`` change, remove or affect."""
    kinds = {change.name: str(change.kind) for change in changes
             if change.section in WAIVABLE_SECTIONS and change.kind != "added"}
    return [TouchedWaiver(number, waiver.rule, waiver.path, waiver.approved_by,
                          str(waiver.until), kinds[waiver.rule])
            for number, waiver in enumerate(waivers) if waiver.rule in kinds]
