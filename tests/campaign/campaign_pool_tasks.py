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
