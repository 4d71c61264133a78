"""What the evaluation stores of the per-sample collision signals gives them back exactly:
contacts as intervals, clearance as the profile the report's run panel draws."""

from __future__ import annotations

import numpy as np
from hypothesis import given
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from idefix_rules.report.runs import run_series
from idefix_rules.results.collisions import (
    clearance_profile,
    contact_from_intervals,
    contact_intervals,
)


@given(arrays(np.int8, st.tuples(st.integers(1, 4), st.integers(1, 30), st.just(3),
                                 st.just(3)), elements=st.integers(0, 2)))
def test_contacts_come_back_from_their_intervals(contact: np.ndarray) -> None:
    rows = np.arange(contact.shape[0]) * 3 + 1  # the path's run numbers, with gaps
    table = contact_intervals(contact, rows)
    np.testing.assert_array_equal(contact_from_intervals(table, rows, contact.shape[1]),
                                  contact)
    # a chunk of some of the runs takes only its own
    some = rows[::2]
    np.testing.assert_array_equal(contact_from_intervals(table, some, contact.shape[1]),
                                  contact[::2])
    # as the scoring takes them: float64, the type the evaluation computes with
    as_float = contact_from_intervals(table, rows, contact.shape[1], dtype=np.float64)
    assert as_float.dtype == np.float64
    np.testing.assert_array_equal(as_float, contact.astype(np.float64))


@given(st.integers(1, 400), st.integers(0, 399))
def test_the_stored_clearance_profile_is_the_run_panels_series(samples: int, seed: int) -> None:
    rng = np.random.default_rng(seed)
    t = np.arange(samples, dtype=float)[None]
    clearance = rng.random((1, samples, 3))
    signals = {"t": t, "x": rng.random((1, samples)), "y": rng.random((1, samples)),
               "collision.clearance": clearance}
    risk = np.zeros((1, samples))
    computed = run_series(signals, 0, risk, None)
    without = {key: value for key, value in signals.items() if key != "collision.clearance"}
    stored = run_series(without, 0, risk, None,
                        {"collision.clearance": clearance_profile(clearance, t)[0]})
    assert stored == computed
