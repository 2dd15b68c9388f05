"""Thread settings for the small dense matrices of the surrogate, chosen once per process.

The pairwise GP works on matrices of a few hundred rows (Cholesky factors, Newton systems,
kernel blocks). At that size the fork/join cost of a multi-threaded BLAS or torch intra-op
pool outweighs the work, and on a small machine two pools (numpy's BLAS and torch's) compete
for the same cores. One thread per pool is the fastest setting we measured for every
algorithm (``python -m localpbo_core.benchmarks.threads_compute`` prints the comparison).

Rule: unless the user chose a thread count through ``OMP_NUM_THREADS``,
``MKL_NUM_THREADS`` or ``OPENBLAS_NUM_THREADS``, :func:`use_fast_threads` sets torch's
intra-op threads and every loaded BLAS/OpenMP pool (``threadpoolctl``) to one thread. The
``localpbo`` command, the ROS nodes and :func:`~localpbo_core.optimizers.make_optimizer`
call it, so a plain shell gets the fast setting; set one of those variables to opt out.
"""

from __future__ import annotations

import os
import sys

USER_THREAD_VARIABLES = ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS")
"""Environment variables through which a user chooses thread counts (then left alone)."""

FAST_THREADS = 1
"""Threads per pool for the surrogate's matrix sizes."""

_state = {"applied": False}


def user_chose_threads() -> bool:
    """True when the environment sets a thread count (the user's choice is kept)."""
    return any(os.environ.get(name) for name in USER_THREAD_VARIABLES)


def use_fast_threads() -> bool:
    """Apply the rule of the module docstring once per process; True if it set threads.

    Safe to call before or after torch is imported: before, ``OMP_NUM_THREADS`` is set for
    the pools still to start; after, torch and the loaded pools are limited directly.
    """
    if user_chose_threads() and not _state["applied"]:
        return False
    torch = sys.modules.get("torch")
    if _state["applied"] and (torch is None or torch.get_num_threads() == FAST_THREADS):
        return True
    _state["applied"] = True
    os.environ["OMP_NUM_THREADS"] = str(FAST_THREADS)
    if torch is not None:
        torch.set_num_threads(FAST_THREADS)
    from threadpoolctl import threadpool_limits

    threadpool_limits(FAST_THREADS)
    return True
