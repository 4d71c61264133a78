"""A stored campaign: a results file opened to read, with the campaign it was simulated from
rebuilt once from its stored text, and the terrain its runs were simulated on.

Everything that scores stored runs again (``evaluate``, ``diff --results``, ``report``) starts
here, so the campaign, its rover geometry, the initial-position σ, the run context of a path
and the obstacle checker on the stored terrain are made in one way only.

>>> stored = StoredCampaign.open(Path("results/rock-detour/results.h5"))  # doctest: +SKIP
>>> stored.rover, stored.sigma  # doctest: +SKIP
(RoverGeometry(...), 0.01)
>>> context = stored.context("smooth-detour")  # doctest: +SKIP
"""

from __future__ import annotations

import hashlib
from pathlib import Path
from typing import Any

import numpy as np

from idefix_rules.campaign.input.campaign_values import initial_position_sigma, rover_geometry
from idefix_rules.campaign.input.load import Campaign, PathSpec
from idefix_rules.commands import Command, RoverGeometry
from idefix_rules.errors import Span, UserInputError, error
from idefix_rules.results.collisions import CollisionFunction, collision_function
from idefix_rules.results.reader import StoredResults, damaged
from idefix_rules.results.terrain import StoredTerrain, terrain_for_rescoring

STORED_RULEBOOK = "/provenance/rulebook"  # the rulebook text inside results.h5
STORED_CAMPAIGN_TEXT = "/provenance/campaign"  # the campaign text inside results.h5


def rebuilt_campaign(store: StoredResults) -> Campaign:
    """The campaign a results file was simulated from, rebuilt from its stored text (for
    geometry, uncertainty, environment and waivers; the FMU and DEM are not resolved). Its
    spans point into the stored text (``results.h5:/provenance/campaign:LINE:COLUMN``, the
    results file absolute): the campaign file may have changed since, or be gone.

    KeyError when the file holds no campaign text; ValueError (pydantic's validation error)
    or :class:`~idefix_rules.errors.UserInputError` when this version cannot read it."""
    from idefix_rules.campaign.input.field_types import STORED_CAMPAIGN
    from idefix_rules.campaign.input.schema import CampaignFile
    from idefix_rules.campaign.input.yamlsource import load_yaml

    text = store.text("campaign")
    path = str(store.attrs.get("campaign_path", "campaign.yaml"))
    document = load_yaml(text, f"{Path(store.path).resolve()}:{STORED_CAMPAIGN_TEXT}")
    # the checks added since it ran do not refuse it: its results stand
    model = CampaignFile.model_validate(document.data, context=STORED_CAMPAIGN)
    base = Path(path).parent
    paths = tuple(PathSpec(name, index, tuple(Command(c.max_wheel_rate, c.delta_position,
                                                      c.delta_heading) for c in chain))
                  for index, (name, chain) in enumerate(model.paths.items()))
    return Campaign(source=Path(path), text=text,
                    sha256=hashlib.sha256(text.encode("utf-8")).hexdigest(), model=model,
                    paths=paths, rulebook=base / model.rulebook, output=base / model.output,
                    fmu=None, dem=None, runs=model.run_count, seed=model.uncertainty.seed,
                    workers=None, locations=document.locations, adaptive=model.adaptive)


def _first_problem(failure: Exception) -> str:
    """What a failed rebuild says first: pydantic's first error as ``key: message``."""
    errors = getattr(failure, "errors", None)
    if callable(errors):
        try:
            first = errors()[0]
            where = ".".join(str(part) for part in first.get("loc", ()))
            return f"{where}: {first.get('msg', failure)}" if where else str(first.get("msg"))
        except (IndexError, TypeError, AttributeError):
            pass
    return str(failure)


class StoredCampaign:
    """A results file and the campaign rebuilt from it (:func:`rebuilt_campaign`).

    ``campaign`` is None when the stored text cannot be rebuilt (``problem`` says why);
    the rover geometry and σ are then the defaults, and :meth:`require_campaign` raises what
    the rebuild raised. The stored terrain is read on first use (:meth:`ground`)."""

    def __init__(self, store: StoredResults) -> None:
        self.store = store
        self.path = store.path
        self.campaign: Campaign | None = None
        self.problem: Exception | None = None
        try:
            self.campaign = rebuilt_campaign(store)
        except Exception as failure:  # said by whoever needs the campaign
            self.problem = failure
        if self.campaign is not None and store.attrs.get("state") == "complete":
            # a finished campaign stored every path it names (its expectations name them too)
            gone = [spec.name for spec in self.campaign.paths if not store.has_path(spec.name)]
            if gone:
                store.close()
                raise damaged(self.path, f"/paths/{gone[0]}",
                              "missing, though the campaign finished")
        self.rover = rover_geometry(self.campaign) if self.campaign is not None \
            else RoverGeometry()
        self.sigma = initial_position_sigma(self.campaign) if self.campaign is not None \
            else 0.0
        self._ground: StoredTerrain | None = None

    @classmethod
    def open(cls, path: Path) -> StoredCampaign:
        """Open ``path`` read only (``H001``-``H004`` when it is not a results file, or a
        damaged one)."""
        return cls(StoredResults.open(Path(path)))

    def close(self) -> None:
        self.store.close()

    def __enter__(self) -> StoredCampaign:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def require_campaign(self) -> Campaign:
        """The rebuilt campaign; raises what rebuilding it raised (a stored campaign that no
        longer validates, e.g. its FMU moved: D010, said as the user's to put right)."""
        if self.campaign is None:
            assert self.problem is not None
            if isinstance(self.problem, KeyError | ValueError):
                raise UserInputError(error(
                    "D010", f"the stored campaign cannot be read back: "
                            f"{_first_problem(self.problem)}", Span(str(self.path)),
                    hint="re-run the campaign with this version, or read the file with the "
                         "version that wrote it")) from None
            raise self.problem
        return self.campaign

    @property
    def environment(self) -> Any:
        """The campaign's environment section (None when the campaign is not rebuilt)."""
        return self.campaign.model.environment if self.campaign is not None else None

    def ground(self, tolerant: bool = False) -> StoredTerrain:
        """The terrain the runs were simulated on, and what to say about it
        (:func:`~idefix_rules.results.terrain.terrain_for_rescoring`), read once.
        ``tolerant``: a stored terrain this version cannot read gives the rocks on the flat
        datum and a warning saying so, instead of the error (the report's choice)."""
        if self._ground is None:
            try:
                self._ground = terrain_for_rescoring(self.store.file, self.path)
            except Exception as failure:
                if not tolerant:
                    raise
                self._ground = StoredTerrain(None, (
                    f"the stored terrain could not be read ({type(failure).__name__}: "
                    f"{failure}): the rocks are placed on the flat datum",))
        return self._ground

    def rulebook_text(self) -> tuple[str, str]:
        """The stored rulebook's text and the name its spans use
        (``results.h5:/provenance/rulebook``); KeyError when none is stored."""
        return self.store.text("rulebook"), f"{self.path}:{STORED_RULEBOOK}"

    def context(self, name: str, reference: Any = None) -> Any:
        """The run context of path ``name``: its chain, the rover, σ and its reference run
        (``reference``: the one already read, else read here)."""
        from idefix_rules.rulebook import RunContext

        return RunContext(chain=self.store.chain(name), rover=self.rover,
                          initial_position_sigma=self.sigma,
                          reference=self.store.reference(name) if reference is None
                          else reference)

    def collision_function(self, evaluator: Any) -> CollisionFunction | None:
        """The obstacle checker of ``evaluator`` on the stored terrain (None when the
        rulebook reads no collision)."""
        if not getattr(evaluator, "needs_collisions", False):
            return None
        return collision_function(self.require_campaign().model.environment, evaluator,
                                  self.ground().terrain, self.rover)

    def named_areas(self, checked: Any) -> dict[str, Any]:
        """The named areas of a rulebook on the stored terrain, by name."""
        from idefix_rules.campaign.input.environment import named_areas

        return named_areas(self.require_campaign().model.environment, checked,
                           self.ground().terrain)

    def complete_rows(self, name: str) -> np.ndarray:
        """Row numbers of the path's complete runs (empty when it has none)."""
        from idefix_rules.results.runs import complete_rows

        if not self.store.has_path(name) or not self.store.has_runs(name):
            return np.zeros(0, dtype=np.int64)
        return complete_rows(self.store.run_status(name))

    def checked_rulebook(self) -> Any:
        """The stored rulebook, checked: spans point into the stored text
        (``results.h5:/provenance/rulebook:LINE:COLUMN``); KeyError when none is stored,
        :class:`~idefix_rules.errors.UserInputError` when this version rejects it."""
        from idefix_rules.errors import UserInputError
        from idefix_rules.rulebook import check_text

        text, name = self.rulebook_text()
        result = check_text(text, name)
        if result.checked is None:
            raise UserInputError(result.errors, {name: text})
        return result.checked
