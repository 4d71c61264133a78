"""The simulation stage: command rules, reference runs, pre-screen and the Monte Carlo runs on
a local process pool or Dask (``simulate``, ``pool``, ``dask_pool``, ``processes``,
``worker``, ``timeouts``, ``resume``, ``prescreen``); an adaptive campaign's looks
(``campaign.adaptive``) drive it batch by batch."""
