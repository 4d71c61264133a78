"""Task functions for the pool tests (a module, so worker processes can import them)."""

import ctypes
import os
import time


def square(payload):
    return payload * payload


def misbehave(payload):
    if payload == "segfault":
        ctypes.string_at(0)
    if payload == "hang":
        time.sleep(600)
    if payload == "raise":
        raise RuntimeError("model error")
    if payload == "exit":
        os._exit(7)
    return payload


def kill_worker(payload):
    """Like misbehave, and "kill-worker" kills the process that runs the task's child (the Dask
    worker), as the kernel's out-of-memory killer or an operator would."""
    if payload == "kill-worker":
        import signal

        os.kill(os.getppid(), signal.SIGKILL)
        time.sleep(600)
    return misbehave(payload)
