"""Set-up of a local Dask cluster's worker processes (a Dask preload: ``dask_setup`` runs in
each worker process as it starts).

Ctrl-C at a terminal goes to the whole process group, the workers of ``--dask-local``
included. As in the local pool's processes, it is the campaign's to decide: the workers ignore
it and are closed with their cluster, instead of each dying halfway through a run with its
traceback.
"""

from __future__ import annotations

import signal
from typing import Any


def dask_setup(worker: Any) -> None:
    signal.signal(signal.SIGINT, signal.SIG_IGN)
