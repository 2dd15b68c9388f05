"""TuRPBO's Thompson-sampling step: autograd vs analytic-gradient path optimisation.

One full TS selection (App. C.5, TuRPBO table) = draw one pathwise posterior sample path
(paper Sec. 4, 1024 random Fourier features) + evaluate it on 1024 raw candidates in the trust
region + L-BFGS-B from the best 5 inside the box. For d = 33 and p in {165, 330, 495} training
points (a surrogate fitted to seeded random duels: X uniform, consecutive points compared by a
fixed weighted quadratic utility) it prints the median time of one selection with the old
route (torch autograd gradient on every L-BFGS-B evaluation) and the new one (closed-form
gradient in float64 numpy), their ratio, a breakdown of the new route, and the path values
reached by both (the same path for both, so they should match closely). Box: TuRBO's
lengthscale-weighted box of side 0.4 around a training point. Run single-threaded:

    python -m localpbo_core.benchmarks.thompson_compute [--reps 15] [--seed 0]
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Callable, Sequence

import numpy as np
import torch
from torch import Tensor

from localpbo_core.surrogate import PairwiseGPSurrogate
from localpbo_core.threads import use_fast_threads

DIM = 33
SIZES = (165, 330, 495)
NUM_RAW = 1024
NUM_FEATURES = 1024
NUM_RESTARTS = 5
TR_LENGTH = 0.4


def fitted_surrogate(p: int, seed: int) -> PairwiseGPSurrogate:
    """Surrogate fitted (learned hyperparameters) to ``p - 1`` duels of consecutive uniform
    points under ``u(x) = -sum_i a_i (x_i - c_i)^2``, everything drawn from ``seed``."""
    g = torch.Generator().manual_seed(seed)
    X = torch.rand(p, DIM, generator=g, dtype=torch.float64)
    center = torch.rand(DIM, generator=g, dtype=torch.float64)
    weight = 10.0 * torch.rand(DIM, generator=g, dtype=torch.float64)
    y = -(weight * (X - center) ** 2).sum(-1)
    i = torch.arange(p - 1)
    win = y[i] > y[i + 1]
    comp = torch.stack([torch.where(win, i, i + 1), torch.where(win, i + 1, i)], dim=1)
    return PairwiseGPSurrogate.fit(X, comp)


def _plain(path: Callable[[Tensor], Tensor]) -> Callable[[Tensor], Tensor]:
    """Hide ``value_and_grad`` so :func:`thompson_batch` takes the autograd route."""

    def f(x: Tensor) -> Tensor:
        return path(x)

    return f


def one_size(p: int, reps: int, seed: int) -> dict[str, float]:
    """Time ``reps`` TS selections per route on one fitted surrogate; return the figures."""
    from localpbo_core.optimizers.acquisition import thompson_batch
    from localpbo_core.optimizers.trust_region import perturbed_candidates, trust_region_bounds

    surrogate = fitted_surrogate(p, seed)
    X = surrogate.train_inputs.numpy()
    ls = surrogate.lengthscale.numpy()
    rng = np.random.default_rng(seed)
    t_old, t_new, t_draw, t_raw, v_old, v_new = [], [], [], [], [], []
    for r in range(reps):
        center = X[int(rng.integers(0, X.shape[0]))]
        lb, ub = trust_region_bounds(center, ls, TR_LENGTH)
        raw = perturbed_candidates(center, lb, ub, NUM_RAW, rng)
        path_seed = int(rng.integers(0, 2**62))
        results = {}
        for route in ("old", "new"):
            t0 = time.perf_counter()
            path = surrogate.sample_paths(
                1, torch.Generator().manual_seed(path_seed), num_features=NUM_FEATURES
            )
            t1 = time.perf_counter()
            target = _plain(path) if route == "old" else path
            x = thompson_batch(target, raw, lb, ub, num_restarts=NUM_RESTARTS)
            t2 = time.perf_counter()
            with torch.no_grad():
                val = float(path(torch.tensor(x))[0, 0])
            results[route] = (t2 - t0, val)
            if route == "new":
                t_draw.append(t1 - t0)
                t3 = time.perf_counter()
                path.values(raw)
                t_raw.append(time.perf_counter() - t3)
        if r == 0:  # first repetition warms caches and allocators; not timed
            continue
        t_old.append(results["old"][0])
        t_new.append(results["new"][0])
        v_old.append(results["old"][1])
        v_new.append(results["new"][1])
    vo, vn = np.array(v_old), np.array(v_new)
    return {
        "old": float(np.median(t_old)),
        "new": float(np.median(t_new)),
        "draw": float(np.median(t_draw[1:])),
        "raw": float(np.median(t_raw[1:])),
        "v_old": float(np.median(vo)),
        "v_new": float(np.median(vn)),
        "max_diff": float(np.max(np.abs(vo - vn))),
        "new_worse": float(np.max(vo - vn)),
    }


def main(argv: Sequence[str] | None = None) -> int:
    """Run the benchmark and print the table."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--reps", type=int, default=15, help="selections per size (first untimed)")
    parser.add_argument("--seed", type=int, default=0, help="seed of data, boxes and paths")
    parser.add_argument("--sizes", default=",".join(map(str, SIZES)), help="training sizes p")
    args = parser.parse_args(argv)
    use_fast_threads()
    if args.reps < 2:
        raise ValueError("--reps must be >= 2 (the first repetition is not timed)")
    sizes = [int(s) for s in args.sizes.split(",")]
    print(
        f"Thompson selection, d={DIM}, q=1, {NUM_FEATURES} RFF, {NUM_RAW} raw, "
        f"{NUM_RESTARTS} restarts, box side {TR_LENGTH}; median over {args.reps - 1} "
        f"selections, torch threads {torch.get_num_threads()}"
    )
    header = (
        f"{'p':>5} {'old s':>8} {'new s':>8} {'ratio':>6} {'draw s':>8} {'raw s':>8} "
        f"{'value old':>10} {'value new':>10} {'max|diff|':>10} {'max(old-new)':>12}"
    )
    print(header)
    for p in sizes:
        r = one_size(p, args.reps, args.seed)
        print(
            f"{p:>5} {r['old']:>8.4f} {r['new']:>8.4f} {r['old'] / r['new']:>6.1f} "
            f"{r['draw']:>8.4f} {r['raw']:>8.4f} {r['v_old']:>10.4f} {r['v_new']:>10.4f} "
            f"{r['max_diff']:>10.2e} {r['new_worse']:>12.2e}"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
