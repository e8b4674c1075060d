"""Worker processes that end with their parent.

A campaign's or a conveyor run's worker processes must not outlive the process that started
them: killed with SIGKILL, the parent gets no chance to stop them, and they would run their
simulations to the end, holding cores and writing nothing anyone reads. A worker calls
:func:`die_with_parent` first thing. On Linux the kernel then sends it SIGKILL when the parent
dies (``prctl(PR_SET_PDEATHSIG)``); everywhere, a daemon thread also polls the parent's pid
and ends the process when it changes (the worker was re-parented), within ``poll_s``.
Standard library only: the calibration layer uses it without loading any FE code.
"""

from __future__ import annotations

import ctypes
import os
import signal
import sys
import threading
import time

__all__ = ["die_with_parent"]

_PR_SET_PDEATHSIG = 1  # from <linux/prctl.h>


def die_with_parent(poll_s: float = 0.5) -> None:
    """Make this process end when its parent process dies (see the module docstring)."""
    parent = os.getppid()
    if sys.platform.startswith("linux"):
        try:
            libc = ctypes.CDLL(None, use_errno=True)
            libc.prctl(_PR_SET_PDEATHSIG, int(signal.SIGKILL), 0, 0, 0)
        except (OSError, AttributeError):  # pragma: no cover - no libc prctl: polling only
            pass
    if os.getppid() != parent:  # the parent died before the request took effect
        os._exit(1)

    def watch() -> None:
        while True:
            time.sleep(poll_s)
            if os.getppid() != parent:
                os._exit(1)

    threading.Thread(target=watch, name="parent-watch", daemon=True).start()
