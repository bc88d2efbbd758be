"""Worker processes that end with the process that started them.

A ``ProcessPoolExecutor`` worker (forkserver or spawn) blocks on its task queue; if the main
process is killed with SIGKILL it gets no signal and may keep running (and computing) for as long
as its current task lasts, or forever. :func:`exit_with_parent` starts a daemon thread in the
worker that checks, every ``interval`` seconds, that the main process is still alive, and ends the
worker at once (``os._exit``) when it is not.
"""

from __future__ import annotations

import os
import threading
import time

CHECK_INTERVAL = 0.5
"""Seconds between two checks of the main process (a worker outlives it by at most this)."""


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # exists, owned by someone else (cannot be ours, but do not kill on doubt)
        return True
    return True


def exit_with_parent(main_pid: int, interval: float = CHECK_INTERVAL) -> threading.Thread:
    """In a worker: exit as soon as process ``main_pid`` has gone or the worker was re-parented.

    Both conditions are checked: the main pid no longer existing (or being a zombie reaped by no
    one), and the worker's own parent changing (the forkserver that started it exits with the main
    process, and the orphaned worker is adopted by init). Returns the watching thread."""
    first_parent = os.getppid()

    def watch() -> None:
        while True:
            time.sleep(interval)
            if os.getppid() != first_parent or not _alive(main_pid) or _zombie(main_pid):
                os._exit(1)

    t = threading.Thread(target=watch, name="gear-env-lifeline", daemon=True)
    t.start()
    return t


def _zombie(pid: int) -> bool:
    try:
        with open(f"/proc/{pid}/stat", encoding="ascii", errors="replace") as fh:
            return fh.read().rsplit(")", 1)[1].split()[0] == "Z"
    except (OSError, IndexError):
        return False


__all__ = ["CHECK_INTERVAL", "exit_with_parent"]
