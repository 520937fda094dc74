"""Preloaded by every worker process of a sweep's LocalCluster (``cluster.local_cluster``):
the worker ignores SIGINT from here on.

Ctrl-C in a terminal goes to the whole process group, the sweep and its Dask workers; the
sweep stops its study and closes its workers, and workers that took the signal themselves
each printed tracebacks (CancelledError, KeyboardInterrupt).  The sweep cannot hand its
workers an ignored SIGINT: while it ignored SIGINT as they started, a Ctrl-C in that second
was lost and the whole study ran on.
"""

from __future__ import annotations

import signal
import threading

if threading.current_thread() is threading.main_thread():
    signal.signal(signal.SIGINT, signal.SIG_IGN)
