"""What a results file holds that its scores alone do not say: a worst-case search's worlds
instead of draws, or a campaign not simulated to its end. Said alike by ``evaluate`` and
``diff --results`` (and in ``diff --format json``'s ``warnings``).

>>> held_warnings({"state": "complete", "runs_mode": "fixed"}, "out/results.h5", "c.yaml")
[]
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from idefix_rules.campaign.simulation.resume import stored_resume_command
from idefix_rules.results.format import is_search


def held_warnings(attrs: Any, results: Any, source: Any, expectations: bool = False,
                  state: str | None = None) -> list[str]:
    """The warnings about results file ``results`` (root attributes ``attrs``, its campaign
    file ``source``): a worst-case search (``expectations``: the campaign has `expect:`
    entries, which are not checked on it), and a campaign ``state`` (default: the stored one)
    other than complete, with the command that continues it."""
    found = []
    if is_search(attrs):
        unchecked = ("; the campaign's expect: entries are not checked (a search states "
                     "facts about worlds, not about how often they occur): the exit code "
                     "follows the verdicts") if expectations else ""
        found.append(
            f"{results} holds a worst-case search (idefix-verify worst): its runs are the "
            "worlds the search chose, not draws of the campaign's distributions, so each "
            "run's risk holds but a path's mean risk, chances and verdict are not the "
            f"campaign's (docs/worst-case.md){unchecked}")
    state = state or str(attrs.get("state", "complete"))
    if state != "complete":  # its missing runs count as failed: say why
        again = stored_resume_command(attrs, source, Path(results).parent)
        if is_search(attrs):
            found.append(f"{results} holds a worst-case search that is {state}: runs never "
                         f"simulated count as failed; a search cannot be resumed: run it again "
                         f"with `{again}`")
        else:
            found.append(f"{results} holds a campaign that is {state}: runs never simulated "
                         f"count as failed; continue it with `{again}`")
    return found
