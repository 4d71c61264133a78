"""A stored path gated again under another rulebook, as a campaign would gate it: the
rulebook's command rules on the stored chain (``rejected``), then its prescreen on the stored
reference run (``excluded``), the campaign's waivers applied to both. ``evaluate --rulebook``
scores with it, so that a chain the new rulebook would never send is not passed on runs it
would never have simulated, and a path the stored campaign rejected or excluded, which the new
rulebook would simulate, is said to need a run (``not simulated``) instead of keeping the old
rulebook's reason."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from idefix_rules.campaign.input import waivers as waiving
from idefix_rules.campaign.input.wording import DisplayUnits, violation_text
from idefix_rules.campaign.simulation.prescreen import finding_text, prescreen_reference
from idefix_rules.commands import Command, RoverGeometry

# A path the stored campaign did not simulate (rejected or excluded under the rulebook it
# ran with) that the rulebook scoring it now would simulate.
NOT_SIMULATED = "not simulated"
NEEDS_RUN = "this rulebook would: run the campaign to score it"
NOT_SIMULATED_REASON = "the stored campaign did not simulate this path ({was}); " + NEEDS_RUN


def gate_again(result: Any, evaluator: Any, chain: Sequence[Command], rover: RoverGeometry,
               sigma: float, reference: Mapping[str, np.ndarray] | None, collisions: Any,
               campaign_waivers: Sequence[Any], units: DisplayUnits) -> None:
    """Set ``result``'s status, reason and waived command and prescreen rules as the campaign
    would under ``evaluator``'s rulebook (see the module docstring). A path whose reference
    run failed or was never stored keeps its stored status: it has nothing to prescreen."""
    name = result.name
    violations, waived = waiving.split(campaign_waivers, name, "command",
                                       evaluator.check_chain(tuple(chain), rover),
                                       lambda violation: str(violation.rule))
    kept = [rule for rule in result.waivers if rule.kind not in ("command", "prescreen")]
    if violations:
        result.status = "rejected"
        result.reason = "; ".join(violation_text(v, units) for v in violations)
        result.waivers = kept + waived
        return
    if result.status == "rejected" or reference is None:
        # rejected by the command rules it ran with, no reference run was stored: the path
        # needs a run; one whose reference run failed (or was never stored) keeps its status
        result.waivers = kept + waived
        if result.status == "rejected":
            _not_simulated(result)
        return
    findings, waived_prescreen = waiving.split(
        campaign_waivers, name, "prescreen",
        prescreen_reference(evaluator, chain, rover, sigma, reference, collisions),
        lambda finding: str(getattr(finding, "rule", "")))
    result.waivers = kept + waived + waived_prescreen
    if findings:
        result.status = "excluded"
        result.reason = "; ".join(finding_text(f) for f in findings)
    elif result.status == "excluded":
        _not_simulated(result)


def _not_simulated(result: Any) -> None:
    was = f"{result.status}: {result.reason}" if result.reason else result.status
    result.status = NOT_SIMULATED
    result.reason = NOT_SIMULATED_REASON.format(was=was)
