"""The read side of stored campaigns: everything that reads a ``results.h5`` back.

Below the campaign stages, the diff and the report, which reach stored campaigns only
through it (``docs/architecture.md``, "The read side"):

- :mod:`.format`: the file's name, version, run status codes, storage precision;
- :mod:`.reader`: :class:`~.reader.StoredResults`, a results file opened to read (the
  campaign's writer, ``campaign.storage.store.ResultStore``, extends it);
- :mod:`.terrain`: the terrain stored in the file, and which one a re-scoring stands on;
- :mod:`.campaign`: :class:`~.campaign.StoredCampaign`, the campaign rebuilt once from its
  stored text, with its rover geometry, σ, run contexts and obstacle checker;
- :mod:`.runs`: a path's complete runs chunk by chunk, their stored chunks decoded on
  threads (:class:`~.runs.ParallelRuns`; :mod:`.mapped` for format 1 files);
- :mod:`.collisions`: collision signals from the obstacle checker or from the stored
  evaluation;
- :mod:`.scoring`: :func:`~.scoring.score_chunks`, the one function that scores a stored
  path chunk by chunk, and :func:`~.scoring.stored_evaluation`.

Nothing is imported here, so importing a module of the package costs only that module.
"""
