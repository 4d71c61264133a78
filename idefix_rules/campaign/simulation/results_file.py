"""The results file a campaign's simulation writes into: created with the campaign's
provenance (its text, rulebook, FMU, seed and run settings, the terrain), or opened again to
resume once its settings are found to be the campaign's (:func:`open_store`)."""

from __future__ import annotations

import contextlib
import json
from pathlib import Path
from typing import Any

import numpy as np

from idefix_rules import __version__
from idefix_rules.campaign.input import sampling
from idefix_rules.campaign.input.load import Campaign
from idefix_rules.campaign.storage import diskspace
from idefix_rules.campaign.storage.store import (
    FORMAT_VERSION,
    RESUMABLE_FORMAT_VERSIONS,
    ResultStore,
)
from idefix_rules.errors import Span, UserInputError, error
from idefix_rules.fmu.terrain import Terrain
from idefix_rules.results import terrain as stored_terrain
from idefix_rules.results.format import attribute_text
from idefix_rules.results.terrain import TerrainSource, file_sha256
from idefix_rules.shell import command_line
from idefix_rules.timestamps import now_iso


def run_settings(campaign: Campaign) -> dict[str, Any]:
    """The root attributes that say how many runs a campaign asked for (compared on resume)."""
    adaptive = campaign.adaptive
    paired = campaign.model.uncertainty.paired
    if adaptive is None:
        return {"runs": campaign.runs, "runs_mode": "fixed",
                "sampling": campaign.model.uncertainty.method, "paired": paired}

    return {"runs": adaptive.max_runs, "runs_mode": "auto", "min_runs": adaptive.min_runs,
            "batch_runs": adaptive.batch_runs, "sampling": sampling.ADAPTIVE_SAMPLING,
            "paired": paired}


def _same_rulebook(store: ResultStore, evaluator: Any, campaign: Campaign,
                   results: Path) -> None:
    """A resumed campaign keeps the rulebook it started with: its command rules and prescreen
    decided which paths were simulated, and one evaluation reads one rulebook. A rulebook
    edited since is refused (H010); ``evaluate --rulebook`` scores the stored runs with it."""
    stored = store.file.get("provenance/rulebook")
    if stored is None or "sha256" not in stored.attrs:
        return  # written before results kept the rulebook's hash: nothing to compare
    digest = attribute_text(stored.attrs["sha256"])
    if digest == str(evaluator.source_hash):
        return
    started = " ".join(attribute_text(stored.attrs.get(key, "?")) for key in ("name", "version"))
    now = f"{evaluator.name} {evaluator.version}"
    if started == now:
        now += ", edited since"
    store.close()
    rescore = command_line("idefix-verify", "evaluate", results, "--rulebook", campaign.rulebook)
    raise UserInputError(error(
        "H010", f"cannot resume {results}: it was started with rulebook {started} "
                f"(sha256 {digest[:12]}), this campaign's rulebook "
                f"{campaign.rulebook} is {now} (sha256 {str(evaluator.source_hash)[:12]})",
        Span(str(results)),
        hint=f"resume with the rulebook it was started with (its text is stored in "
             f"{results.name}, /provenance/rulebook), then score the runs with the new one: "
             f"{rescore}; or run without --resume to start again"))


def open_store(campaign: Campaign, evaluator: Any, fmu_path: Path, results: Path,
               resume: bool, terrain: tuple[Terrain, TerrainSource] | None,
               terrain_seen: bool = True) -> ResultStore:
    """The results file to simulate into: created (``terrain_seen``: whether the FMU takes the
    campaign's terrain file, stored for the report's note), or opened again to resume after
    its settings were compared with the campaign's."""
    fmu_hash = file_sha256(fmu_path)
    if resume and results.exists():
        diskspace.require(results.parent, 0, f"continue {results.name}")
        store = ResultStore.open(results, writable=True)
        expected = {"format_version": FORMAT_VERSION, "campaign_sha256": campaign.sha256,
                    **run_settings(campaign), "seed": campaign.seed, "fmu_sha256": fmu_hash}
        for key, value in expected.items():
            stored = store.attrs.get(key)
            if key == "paired" and stored is None:
                stored = False  # written before campaigns were paired: every path drew its own
            if key == "format_version" and stored in RESUMABLE_FORMAT_VERSIONS:
                continue  # its full-size run datasets are a block allocation of every row
            if stored != value:
                store.close()
                shown = stored.item() if isinstance(stored, np.generic) else stored
                raise UserInputError(error(
                    "H010", f"cannot resume {results}: its {key} is {shown!r}, "
                            f"this campaign's is {value!r}", Span(str(results)),
                    hint="resume with the same campaign file, --runs, --max-runs, --min-runs, "
                         "--seed and FMU, or choose another --out"))
        _same_rulebook(store, evaluator, campaign, results)
        resumed = json.loads(str(store.attrs.get("resumed", "[]")))
        store.attrs["resumed"] = json.dumps([*resumed, now_iso()])
        if terrain is not None and not stored_terrain.has_terrain(store.file):
            # written before results held their terrain: the one the runs now see is stored
            with store.structural_change(stored_terrain.stored_bytes(terrain[0]),
                                         f"store the terrain in {results.name}", 0):
                stored_terrain.write_terrain(store.file, *terrain)
        # paths allocated now grow by blocks; the terrain is stored
        store.attrs["format_version"] = FORMAT_VERSION
        return store
    rulebook_text = campaign.rulebook.read_text(encoding="utf-8")
    if terrain is not None:  # checked before the file is made (or the last one set aside)
        diskspace.require(results.parent, stored_terrain.stored_bytes(terrain[0]),
                          f"store the terrain in {results.name}")
    store = ResultStore.create(results, {
        "campaign_name": campaign.name,
        "campaign_path": str(campaign.source),
        "campaign_sha256": campaign.sha256,
        "package_version": __version__,
        "fmu_path": str(fmu_path),
        "fmu_sha256": fmu_hash,
        "seed": campaign.seed,
        **run_settings(campaign),
        "seed_derivation": sampling.seed_derivation(campaign.model.uncertainty.paired),
        "started": now_iso(),
        "resumed": "[]",
        "finished": "",
        "state": "running",
        "output_interval": campaign.model.simulation.output_interval,
        "terrain_seen": terrain_seen,
    }, {"campaign": campaign.text, "rulebook": rulebook_text})
    try:
        text = store.file["provenance"]["rulebook"]
        text.attrs["name"] = evaluator.name
        text.attrs["version"] = evaluator.version
        text.attrs["sha256"] = evaluator.source_hash
        text.attrs["path"] = str(campaign.rulebook)
        if terrain is not None:
            stored_terrain.write_terrain(store.file, *terrain)
        store.file.flush()
    except BaseException:
        with contextlib.suppress(Exception):  # the error on its way says what went wrong
            store.close()
        raise
    return store
