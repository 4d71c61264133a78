"""Collision checks spread over worker processes give exactly the single-process result."""

import os
import signal

import numpy as np

from idefix_rules.results.scoring import with_collisions


def _fake_collisions(poses, rows):
    # A pure function of the poses (like the real checker), cheap enough for a test.
    far = np.abs(poses["y"]).max(axis=1) > 0.1
    hits = far.astype(np.int64)[:, None, None] * np.ones((1, 3, 3))
    return {"collision.hits": hits}, [{"run": int(r)} for r in rows]


def _chunks(count):
    rng = np.random.default_rng(7)
    for begin in range(0, count * 5, 5):
        rows = np.arange(begin, begin + 5)
        signals = {key: rng.normal(0, 0.1, (5, 40))
                   for key in ("t", "x", "y", "z", "roll", "pitch", "yaw", "energy")}
        yield rows, signals


def test_forked_collision_checks_equal_the_serial_ones_in_chunk_order():
    serial = list(with_collisions(_chunks(9), _fake_collisions, workers=1))
    forked = list(with_collisions(_chunks(9), _fake_collisions, workers=2))
    assert len(serial) == len(forked) == 9
    for (rows_a, _, (signals_a, details_a)), (rows_b, _, (signals_b, details_b)) in zip(
            serial, forked, strict=True):
        assert np.array_equal(rows_a, rows_b)
        assert np.array_equal(signals_a["collision.hits"], signals_b["collision.hits"])
        assert details_a == details_b


PARENT = os.getpid()


def _killed_in_a_worker(poses, rows):
    """The fake check, whose worker process is killed from outside (as the out-of-memory
    killer would) when it is given the chunk of run 20; checked in the parent it is cheap."""
    if os.getpid() != PARENT and 20 in rows:
        os.kill(os.getpid(), signal.SIGKILL)
    return _fake_collisions(poses, rows)


def test_a_collision_check_worker_killed_from_outside_loses_no_chunk():
    """The pool breaks (BrokenProcessPool: an "internal error" with its traceback, the
    evaluation lost): the chunks the dead worker held, and every later one, are checked in
    this process, with the serial result."""
    serial = list(with_collisions(_chunks(9), _fake_collisions, workers=1))
    survived = list(with_collisions(_chunks(9), _killed_in_a_worker, workers=2))
    assert [rows.tolist() for rows, _, _ in survived] == \
        [rows.tolist() for rows, _, _ in serial]
    for (_, _, (signals_a, details_a)), (_, _, (signals_b, details_b)) in zip(
            serial, survived, strict=True):
        assert np.array_equal(signals_a["collision.hits"], signals_b["collision.hits"])
        assert details_a == details_b
