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


# A marked task's process writes its pid into the folder MARK names, then waits DELAY seconds
# before the task proper: a test (tests/campaign/test_campaign_killed_workers.py) then kills it
# from outside while it runs that task, as the kernel's out-of-memory killer would.
MARK = "IDEFIX_TEST_MARK"
MARKED = "IDEFIX_TEST_MARKED"  # the marked run of a campaign: "<commands>:<initial.x!r>"
DELAY = 3.0


def _announce():
    folder = os.environ.get(MARK)
    if not folder:
        return
    pid = os.getpid()
    temporary = os.path.join(folder, f".{pid}.tmp")
    with open(temporary, "w") as handle:
        handle.write(str(pid))
    os.rename(temporary, os.path.join(folder, str(pid)))
    time.sleep(DELAY)


def marked(payload):
    """Like misbehave; "marked" and "marked-segfault" announce their process first."""
    if payload.startswith("marked"):
        _announce()
        payload = payload.removeprefix("marked").removeprefix("-") or "marked"
    return misbehave(payload)


def marked_simulate(task):
    """The campaign's task function; the marked run (its chain's length and its initial.x)
    announces itself."""
    from idefix_rules.campaign.simulation.worker import simulate

    if f"{len(task.chain)}:{dict(task.parameters).get('initial.x')!r}" == os.environ.get(MARKED):
        _announce()
    return simulate(task)


def pid(payload):
    """The process that ran the task."""
    return os.getpid()


def count_pools(monkeypatch):
    """Make the campaign's local pools count themselves: returns ``(made, maps)``, each pool's
    ``persistent`` flag as it is made and each map's task count as it starts."""
    from idefix_rules.campaign.simulation import run_tasks

    made, maps = [], []

    class Counted(run_tasks.LocalPool):
        def __init__(self, *args, **kwargs):
            super().__init__(*args, **kwargs)
            made.append(self.persistent)

        def map(self, tasks):
            listed = list(tasks)
            maps.append(len(listed))
            return super().map(listed)

    monkeypatch.setattr(run_tasks, "LocalPool", Counted)
    return made, maps


def continued(payload):
    """``(name, seconds, after)``: the value ``("ran", name)`` after ``seconds``, handed back
    at once, then the work after it (``Continued``): ``("checked", name)`` after ``after``
    seconds, or "segfault", "raise" or "hang" there."""
    from idefix_rules.campaign.simulation.processes import Continued

    name, seconds, after = payload
    time.sleep(seconds)

    def then():
        if isinstance(after, str):
            misbehave(after)
        else:
            time.sleep(after)
        return ("checked", name)

    return Continued(("ran", name), then)


def continued_alone(payload):
    """A ``Continued`` value without work after it: a plain answer."""
    from idefix_rules.campaign.simulation.processes import Continued

    return Continued(payload)


def retiring(payload):
    """The process that ran the task; "retire" answers it as a ``Retire`` (the process ends
    after answering, as one whose FMU returned Fatal), "retire-failed" answers a failure so."""
    from idefix_rules.campaign.simulation.processes import Retire

    if payload == "retire":
        return Retire(os.getpid())
    if payload == "retire-failed":
        return Retire(failure=RuntimeError("corrupted for good"))
    return os.getpid()


def surroundings(name: str) -> tuple[str, str | None]:
    """The folder a run works in and the value of the environment variable ``name`` there."""
    return os.getcwd(), os.environ.get(name)
