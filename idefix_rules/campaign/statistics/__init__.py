"""The bounds a decision rests on: exact Bernoulli bounds (``bernoulli``), confidence
sequences (``sequential``), a path's judged bounds (``bounds``), the α budget (``budget``),
paired comparisons (``pairwise``), when an adaptive campaign stops (``stopping``), the runs
still needed (``runs_needed``) and simulated error rates (``error_rates``)."""
