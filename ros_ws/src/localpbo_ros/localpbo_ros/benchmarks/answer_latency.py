"""Benchmark: time from an answer to the next duel, with and without speculation.

A person judging duels waits, after each answer, for the optimizer to decide the next ask.
This script drives the optimizer node's :class:`~localpbo_ros.driver.Driver` (the node's own
bookkeeping: ``offer`` the decoded outcome, ``ask``, encode the candidate and request
messages) on Hopper (d = 33) with the simulated oracle up to ``--duels`` duels; over the last
``--measure`` duels it times every answer that completes an ask (an answer to an earlier duel
of an ask of several needs no decision: the next duel is already out), for the same answer
and the same state:

* **plain**: ``offer`` + ``ask`` on a fork of the driver, the work the node does today;
* **speculative**: the next ask prepared for every possible answer first (untimed: the person
  is watching), then ``offer`` (adopting the prepared branch) + ``ask``.

It checks that both give the same candidates and requests, bit for bit, prints median and 95th
percentile per algorithm and their ratio, and the CPU the speculation spent per duel (one
decision per possible answer). Asserts nothing about time.

Run: ``python -m localpbo_ros.benchmarks.answer_latency [--duels 400] [--measure 60]
[--algorithms turpbo,prefsqp,gipbor]``.
"""

from __future__ import annotations

import argparse
import copy
import time

import numpy as np

from localpbo_core.session import episode_seed
from localpbo_core.settings import RunSettings
from localpbo_core.threads import use_fast_threads
from localpbo_msgs_py import DuelOutcome
from localpbo_ros.driver import Driver, Work, make_run_config


def _encode(work: Work) -> None:
    for cand in work.candidates:
        cand.encode()
    for req in work.requests:
        req.encode()


def _fork(driver: Driver) -> Driver:
    twin = copy.copy(driver)
    twin.session = driver.session.fork()
    twin.accepted = list(driver.accepted)
    return twin


def _answered(driver: Driver, answer: DuelOutcome) -> tuple[float, Work | None]:
    """Offer ``answer`` and ask for the next work (encoded for the wire); the seconds that
    took and the work (None once the run is done)."""
    t0 = time.perf_counter()
    assert driver.offer(answer).accepted
    work = None if driver.done else driver.ask()
    if work is not None:
        _encode(work)
    return time.perf_counter() - t0, work


def measure(algorithm: str, duels: int, n_measure: int, seed: int) -> dict[str, object]:
    """Drive one run to ``duels`` duels; time the last ``n_measure`` answers both ways."""
    settings = RunSettings(algorithm=algorithm, problem="hopper", seed=seed, budget=duels + 1)
    driver = Driver(make_run_config(f"latency-{algorithm}", settings))
    problem = driver.session.problem
    oracle = driver.session.oracle()
    values: dict[int, float] = {}
    plain: list[float] = []
    fast: list[float] = []
    spent: list[float] = []
    work = driver.ask()
    t_run = time.perf_counter()
    while True:
        for cand in work.candidates:
            theta = np.asarray(cand.theta, dtype=np.float64)
            values[cand.candidate_id] = float(
                problem.evaluate_native(theta, episode_seed(seed, cand.candidate_id))
            )
        answers = []
        for req in work.requests:
            first = oracle.first_wins(req.duel_id, values[req.first_id], values[req.second_id])
            answers.append(DuelOutcome.decisive(req, req.first_id if first else req.second_id))
        for early in answers[:-1]:  # an ask of several duels: the last answer decides
            assert driver.offer(early).accepted
        answer = answers[-1]
        if driver.n_duels >= duels - n_measure:
            seconds, expect = _answered(_fork(driver), answer)
            plain.append(seconds)
            spec = driver.speculate()
            assert spec is not None
            spec.join()
            spent.append(sum(b.seconds for b in spec.branches()))
            seconds, got = _answered(driver, answer)
            fast.append(seconds)
            same = (expect is None and got is None) or (
                expect is not None and got is not None and expect == got
            )
            if not same:
                raise AssertionError(f"{algorithm}: speculation changed duel {answer.duel_id}")
        else:
            assert driver.offer(answer).accepted
            got = None if driver.done else driver.ask()
        if got is None:
            break
        work = got
    return {
        "algorithm": algorithm,
        "duels": driver.n_duels,
        "plain": np.array(plain),
        "fast": np.array(fast),
        "spent": np.array(spent),
        "run_s": time.perf_counter() - t_run,
    }


def main(argv: list[str] | None = None) -> None:
    """Print the answer-to-next-duel latency per algorithm, plain and speculative."""
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--duels", type=int, default=400)
    parser.add_argument("--measure", type=int, default=60)
    parser.add_argument("--algorithms", default="turpbo,prefsqp,gipbor")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)
    use_fast_threads()
    print(
        f"Hopper (d = 33), {args.duels} duels; answers completing an ask within the last "
        f"{args.measure} duels timed (offer + ask + encode; ms)"
    )
    head = f"{'algorithm':<10}{'n':>4}{'plain med':>11}{'p95':>8}{'spec med':>10}{'p95':>8}"
    print(f"{head}{'ratio':>9}{'spec CPU/duel':>15}{'same':>6}")
    for algorithm in args.algorithms.split(","):
        r = measure(algorithm, args.duels, args.measure, args.seed)
        plain, fast, spent = (np.asarray(r[k]) * 1e3 for k in ("plain", "fast", "spent"))
        ratio = np.median(plain) / np.median(fast)
        print(
            f"{algorithm:<10}{len(plain):>4}"
            f"{np.median(plain):>11.1f}{np.percentile(plain, 95):>8.1f}"
            f"{np.median(fast):>10.2f}{np.percentile(fast, 95):>8.2f}{ratio:>8.0f}x"
            f"{np.median(spent):>15.0f}{'yes':>6}"
        )


if __name__ == "__main__":
    main()
