"""The thread rule (localpbo_core.threads): one thread per pool unless the user chose."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest

from localpbo_core.threads import USER_THREAD_VARIABLES

PROBE = """
import json
from threadpoolctl import threadpool_info
from localpbo_core.session import RunSettings, Session
Session(RunSettings(algorithm="turpbo", problem="hartmann6", budget=4))
import torch
blas = sorted({p["num_threads"] for p in threadpool_info() if p["user_api"] == "blas"})
print(json.dumps({"torch": torch.get_num_threads(), "blas": blas}))
"""


def threads_in_fresh_process(**env_vars: str) -> dict[str, object]:
    env = {k: v for k, v in os.environ.items() if k not in USER_THREAD_VARIABLES}
    env.update(env_vars)
    out = subprocess.run(
        [sys.executable, "-c", PROBE], env=env, capture_output=True, text=True, check=True
    ).stdout
    return json.loads(out.strip().splitlines()[-1])


def test_a_plain_process_gets_one_thread_per_pool() -> None:
    got = threads_in_fresh_process()
    assert got == {"torch": 1, "blas": [1]}


@pytest.mark.skipif((os.cpu_count() or 1) < 2, reason="needs 2 cores to see a user's choice")
def test_a_users_choice_is_kept() -> None:
    got = threads_in_fresh_process(OMP_NUM_THREADS="2")
    assert got["torch"] == 2
