"""Set-up of a local Dask cluster's worker processes (a Dask preload: ``dask_setup`` runs in
each worker process as it starts).

Ctrl-C at a terminal goes to the whole process group, the workers of ``--dask-local``
included. As in the local pool's processes, it is the campaign's to decide: the workers ignore
it and are closed with their cluster, instead of each dying halfway through a run with its
traceback. A worker forked from the campaign's fork server starts in the folder the campaign
works in, as a spawned one would.
"""

from __future__ import annotations

import os
import signal
from typing import Any

# The folder the campaign works in, for workers forked from a fork server that started in
# another (their environment comes from the campaign through the nanny).
WORKING_FOLDER = "IDEFIX_DASK_WORKING_FOLDER"


def dask_setup(worker: Any) -> None:
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    folder = os.environ.get(WORKING_FOLDER)
    if folder:
        os.chdir(folder)
