"""The derivative-aware pairwise GP surrogate of paper Sec. 4.

Laplace-approximated pairwise GP with probit likelihood (sigma_n = 1, BoTorch convention), an
ARD squared-exponential ``ScaleKernel`` prior, and the joint posterior of ``f``, ``grad f`` and
``vec(hess f)`` at any point (paper eqs. (10) "joint derivative predictive" and (11) "general
covariance block").

"Can't tell" answers (``ties``) enter through the ordinal probit of :mod:`.ordinal`
(Chu & Ghahramani 2005) with the indifference threshold ``tie_threshold``; 0 and no ties is
the paper's model exactly.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np
import torch
from torch import Tensor

if TYPE_CHECKING:
    from .sampling import SamplePaths

from .data import DUPLICATE_ATOL, consolidate, validate_comparisons, validate_points
from .hyperparameters import (
    LENGTHSCALE_BOUNDS,
    OUTPUTSCALE_BOUNDS,
    FitResult,
    learn_hyperparameters,
)
from .kernel import kernel_derivatives, prior_block, se_kernel, se_kernel_exact
from .laplace import hessian_weights, likelihood_hessian, probit_terms, whitened_precision
from .ordinal import Ordinal
from .protocol import Surrogate

# The start of a cold fit: BoTorch's initial values under the paper's constraints (raw
# parameter 0 of Interval(0.05, 0.5) and Interval(0.005, 200), i.e. the interval midpoints).
_DEFAULT_LENGTHSCALE = 0.275
_DEFAULT_OUTPUTSCALE = 100.0
# Below this outputscale the model predicts near coin flips (utility std 0.32 against the probit
# noise 1): a warm-started fit that ends here is compared with a fit from the default start.
_FLAT_OUTPUTSCALE = 0.1


def _as_batch(x: Tensor, d: int, name: str = "x") -> tuple[Tensor, bool]:
    if not isinstance(x, Tensor):
        raise ValueError(f"{name} must be a torch.Tensor, got {type(x).__name__}")
    if x.dtype != torch.float64:
        raise ValueError(f"{name} must have dtype torch.float64, got {x.dtype}")
    if x.ndim == 1 and x.shape[0] == d:
        return x.unsqueeze(0), True
    if x.ndim == 2 and x.shape[1] == d:
        return x, False
    raise ValueError(f"{name} must have shape ({d},) or (N, {d}), got {tuple(x.shape)}")


def _check_lengthscale(lengthscale: object, d: int) -> Tensor | None:
    if lengthscale is None:
        return None
    ls = torch.as_tensor(lengthscale, dtype=torch.float64)
    if ls.ndim == 0:
        ls = ls.expand(d).clone()
    if ls.shape != (d,):
        raise ValueError(f"lengthscale must be a float or a ({d},) tensor, got {tuple(ls.shape)}")
    if not torch.isfinite(ls).all() or (ls <= 0).any():
        raise ValueError("lengthscale must be finite and positive")
    return ls.detach().clone()


def _check_outputscale(outputscale: object) -> float | None:
    if outputscale is None:
        return None
    value = float(torch.as_tensor(outputscale))
    if not math.isfinite(value) or value <= 0:
        raise ValueError(f"outputscale must be finite and positive, got {value}")
    return value


class PairwiseGPSurrogate(Surrogate):
    """Laplace-approximated pairwise GP with derivative-aware posterior (paper Sec. 4).

    Build with :meth:`fit`. Attributes: ``lengthscale`` ``(d,)``, ``outputscale`` (float),
    ``train_inputs`` (unique points ``(p, d)``), ``utility`` (MAP ``f_hat`` at them),
    ``log_marginal_likelihood`` (Laplace evidence + log hyperpriors at the fit),
    ``winners``/``losers`` (duels as indices into ``train_inputs``), ``index_map`` (row of the
    fitted ``X`` -> row of ``train_inputs``), ``eps_reg``, ``z_limit``, ``jitter``,
    ``likelihood_hessian`` (``C`` of eq. (8)), ``chol_K``, ``chol_B``, ``tie`` (``(m,)`` bool:
    rows of ``winners``/``losers`` that are "can't tell" answers, first/second) and
    ``tie_threshold`` (the ordinal model's ``eps``).
    """

    def __init__(
        self,
        train_inputs: Tensor,
        winners: Tensor,
        losers: Tensor,
        lengthscale: Tensor,
        outputscale: float,
        L: Tensor,
        v_hat: Tensor,
        log_marginal_likelihood: float,
        z_limit: float | None,
        eps_reg: float,
        jitter: float,
        n_evaluations: int = 0,
        index_map: Tensor | None = None,
        fit_curvature: np.ndarray | None = None,
        tie: Tensor | None = None,
        tie_threshold: float = 0.0,
    ) -> None:
        self.train_inputs = train_inputs
        self.tie = torch.zeros_like(winners, dtype=torch.bool) if tie is None else tie
        self.tie_threshold = float(tie_threshold)
        ordinal = Ordinal(self.tie, self.tie_threshold)
        self.ordinal: Ordinal | None = None if ordinal.is_plain else ordinal
        self.index_map = torch.arange(train_inputs.shape[0]) if index_map is None else index_map
        self.winners = winners
        self.losers = losers
        self.lengthscale = lengthscale
        self.outputscale = outputscale
        self.z_limit = z_limit
        self.eps_reg = eps_reg
        self.jitter = jitter
        self.log_marginal_likelihood = log_marginal_likelihood
        self.n_evaluations = n_evaluations
        # BFGS Hessian approximation of the hyperparameter objective at this fit: the next
        # warm-started fit starts its solve from it (see hyperparameters.learn_hyperparameters).
        self.fit_curvature = fit_curvature
        self._L = L
        self._v_hat = v_hat
        self.utility = L @ v_hat
        # alpha = K^{-1} f_hat, so mu(x) = k(x, X) alpha (paper Sec. 4, predictive means).
        self._alpha = torch.linalg.solve_triangular(
            L.transpose(0, 1), v_hat.unsqueeze(-1), upper=True
        ).squeeze(-1)
        t = probit_terms(self.utility, winners, losers, z_limit, self.ordinal)
        self._probit = t
        # B = I + L^T C_hat L with C_hat = C + eps_reg I (paper Sec. 4)
        B = whitened_precision(L, winners, losers, hessian_weights(t))
        if eps_reg > 0:
            B = B + eps_reg * (L.transpose(0, 1) @ L)
        self._LB = torch.linalg.cholesky(B)
        self._LB_by_eps: dict[float, Tensor] = {float(eps_reg): self._LB}

    @property
    def likelihood_hessian(self) -> Tensor:
        """``C`` of eq. (8) at the MAP, dense ``(p, p)`` (without ``eps_reg``)."""
        return likelihood_hessian(self._probit, self.winners, self.losers, self.utility.shape[0])

    # ------------------------------------------------------------------ construction
    @classmethod
    def fit(
        cls,
        X: Tensor,
        comparisons: Tensor,
        lengthscale: float | Tensor | None = None,
        outputscale: float | None = None,
        warm_start: Surrogate | None = None,
        *,
        z_limit: float | None = None,
        eps_reg: float = 0.0,
        jitter: float = 1e-8,
        duplicate_atol: float = DUPLICATE_ATOL,
        maxiter: int = 200,
        solver: str = "carried-bfgs",
        form: str = "auto",
        ties: Tensor | None = None,
        tie_threshold: float = 0.0,
    ) -> PairwiseGPSurrogate:
        """Fit the surrogate to duels.

        Args:
            X: ``(n, d)`` float64 points in ``[0, 1]^d``.
            comparisons: ``(m, 2)`` long ``[winner_index, loser_index]`` rows into ``X`` (may
                be empty, ``(0, 2)``, when ``ties`` has rows).
            lengthscale: None (learn, within ``[0.05, 0.5]``), a float or a ``(d,)`` tensor
                (fixed, the paper's "within-model" setting).
            outputscale: None (learn, within ``[0.005, 100]``) or a fixed float.
            warm_start: a previous fit; hyperparameters, the MAP (extended to new points by
                the previous posterior mean) and the solver's curvature start from it. Without
                it the solve starts from BoTorch's initial values (lengthscales 0.275,
                outputscale 100); a warm fit that ends with outputscale < 0.1 (a model that
                predicts near coin flips) is compared with a fit from that start, keeping the
                higher objective.
            z_limit: clamp ``|z|`` in the likelihood like BoTorch (3.0); None = exact probit.
            eps_reg: ``C_hat = C + eps_reg I`` in all posterior covariances (paper Sec. 4). The
                covariances are computed without inverting ``C``, so 0 is safe.
            jitter: relative diagonal jitter on ``K`` (grown automatically if needed).
            duplicate_atol: points closer than this in every coordinate are merged.
            maxiter: iteration cap of the hyperparameter solver.
            solver: ``"carried-bfgs"`` (default) or ``"l-bfgs-b"`` (scipy; the reference), see
                :func:`~localpbo_core.surrogate.hyperparameters.learn_hyperparameters`.
            form: how the Laplace approximation is computed while learning: ``"auto"``
                (default), ``"duels"`` or ``"whitened"``, see
                :func:`~localpbo_core.surrogate.hyperparameters.evaluate_with_gradient`.
            ties: ``(k, 2)`` long ``[first, second]`` rows of "can't tell" answers, or None.
            tie_threshold: the indifference threshold ``eps >= 0`` of the ordinal likelihood
                (:mod:`.ordinal`); decisive duels then have ``P = Phi((g - eps) / sqrt(2))``.
                Ties need ``eps > 0``. 0 without ties is the paper's probit exactly.
        """
        X = validate_points(X, "X")
        d = X.shape[1]
        n_ties = 0
        if ties is not None:
            ties = validate_comparisons(ties, X.shape[0], "ties", min_rows=0)
            n_ties = int(ties.shape[0])
        comparisons = validate_comparisons(comparisons, X.shape[0], min_rows=0 if n_ties else 1)
        eps = float(tie_threshold)
        if not math.isfinite(eps) or eps < 0:
            raise ValueError(f"tie_threshold must be finite and >= 0, got {tie_threshold}")
        if n_ties and eps == 0:
            raise ValueError("ties need tie_threshold > 0 (a tie has probability 0 at eps = 0)")
        if eps > 0 and z_limit is not None:
            raise ValueError("tie_threshold > 0 needs the exact probit (z_limit=None)")
        ls_fixed = _check_lengthscale(lengthscale, d)
        os_fixed = _check_outputscale(outputscale)
        if eps_reg < 0 or not math.isfinite(eps_reg):
            raise ValueError(f"eps_reg must be finite and >= 0, got {eps_reg}")
        if warm_start is not None and warm_start.train_inputs.shape[1] != d:
            raise ValueError("warm_start was fitted in a different dimension")
        data = consolidate(X, comparisons, duplicate_atol, ties)
        Xu = data.X
        ordinal: Ordinal | None = Ordinal(data.tie, eps)
        if ordinal is not None and ordinal.is_plain:
            ordinal = None

        if ls_fixed is not None:
            ls0 = ls_fixed
        elif warm_start is not None:
            ls0 = warm_start.lengthscale.clone()
        else:
            ls0 = torch.full((d,), _DEFAULT_LENGTHSCALE, dtype=torch.float64)
        if os_fixed is not None:
            os0 = os_fixed
        elif warm_start is not None:
            os0 = warm_start.outputscale
        else:
            os0 = _DEFAULT_OUTPUTSCALE
        if warm_start is not None:
            with torch.no_grad():
                f_init = warm_start.mean(Xu)
        else:
            f_init = torch.zeros(Xu.shape[0], dtype=torch.float64)

        def learn(
            ls_start: Tensor, os_start: float, f_start: Tensor, curvature0: np.ndarray | None
        ) -> FitResult:
            return learn_hyperparameters(
                Xu,
                data.winners,
                data.losers,
                ls_start,
                os_start,
                learn_lengthscale=ls_fixed is None,
                learn_outputscale=os_fixed is None,
                f_init=f_start,
                jitter=jitter,
                z_limit=z_limit,
                maxiter=maxiter,
                solver=solver,
                form=form,
                curvature0=curvature0,
                ordinal=ordinal,
            )

        res = learn(ls0, os0, f_init, None if warm_start is None else warm_start.fit_curvature)
        if warm_start is not None and os_fixed is None and res.outputscale < _FLAT_OUTPUTSCALE:
            # The evidence has a second, degenerate basin where the model explains nothing
            # (outputscale at the prior's lower edge); a warm-started local solve that lands
            # there is checked against a solve from the default start; the better one is kept.
            ls_default = ls0 if ls_fixed is not None else torch.full_like(ls0, _DEFAULT_LENGTHSCALE)
            alt = learn(ls_default, _DEFAULT_OUTPUTSCALE, torch.zeros_like(f_init), None)
            total = res.n_evaluations + alt.n_evaluations
            if alt.log_marginal_likelihood > res.log_marginal_likelihood:
                res = alt
            res.n_evaluations = total
        curvature = res.curvature
        nothing_learned = ls_fixed is not None and os_fixed is not None
        if nothing_learned and warm_start is not None:  # keep the last curvature for later fits
            curvature = warm_start.fit_curvature
        return cls(
            train_inputs=Xu,
            winners=data.winners,
            losers=data.losers,
            lengthscale=res.lengthscale,
            outputscale=res.outputscale,
            L=res.L,
            v_hat=res.v_hat,
            log_marginal_likelihood=res.log_marginal_likelihood,
            z_limit=z_limit,
            eps_reg=eps_reg,
            jitter=jitter,
            n_evaluations=res.n_evaluations,
            index_map=data.index_map,
            fit_curvature=curvature,
            tie=data.tie,
            tie_threshold=eps,
        )

    @property
    def dim(self) -> int:
        return int(self.train_inputs.shape[1])

    @property
    def bounds(self) -> dict[str, tuple[float, float]]:
        """Hyperparameter bounds used when learning."""
        return {"lengthscale": LENGTHSCALE_BOUNDS, "outputscale": OUTPUTSCALE_BOUNDS}

    # ------------------------------------------------------------------ internals
    def _chol_B(self, eps_reg: float | None) -> Tensor:
        """Cholesky of ``B = I + L^T (C + eps_reg I) L`` (cached per ``eps_reg``)."""
        if eps_reg is None:
            return self._LB
        eps = float(eps_reg)
        if eps < 0 or not math.isfinite(eps):
            raise ValueError(f"eps_reg must be finite and >= 0, got {eps_reg}")
        if eps not in self._LB_by_eps:
            L = self._L
            B = whitened_precision(L, self.winners, self.losers, hessian_weights(self._probit))
            if eps > 0:
                B = B + eps * (L.transpose(0, 1) @ L)
            self._LB_by_eps[eps] = torch.linalg.cholesky(B)
        return self._LB_by_eps[eps]

    def _whiten(self, k: Tensor, eps_reg: float | None = None) -> tuple[Tensor, Tensor]:
        """For kernel columns ``k`` ``(p, r)`` return ``U = L^{-1} k`` and ``W = L_B^{-1} U``, so
        ``k_a^T (K + C_hat^{-1})^{-1} k_b = U_a^T U_b - W_a^T W_b`` because
        ``(K + C_hat^{-1})^{-1} = K^{-1} - K^{-1} (K^{-1} + C_hat)^{-1} K^{-1}`` and
        ``(K^{-1} + C_hat)^{-1} = L B^{-1} L^T`` with ``B = I + L^T C_hat L = L_B L_B^T``.
        No inverse of ``C_hat`` is needed (so ``eps_reg = 0`` is fine)."""
        U = torch.linalg.solve_triangular(self._L, k, upper=False)
        W = torch.linalg.solve_triangular(self._chol_B(eps_reg), U, upper=False)
        return U, W

    def _quad(self, ka: Tensor, kb: Tensor | None = None, eps_reg: float | None = None) -> Tensor:
        """``ka^T (K + C_hat^{-1})^{-1} kb`` for batched columns ``ka`` ``(N, p, r_a)``,
        ``kb`` ``(N, p, r_b)`` (``kb = ka`` if None); result ``(N, r_a, r_b)``."""
        N, p, ra = ka.shape
        Ua, Wa = self._whiten(ka.permute(1, 0, 2).reshape(p, N * ra), eps_reg)
        Ua, Wa = Ua.reshape(p, N, ra), Wa.reshape(p, N, ra)
        if kb is None:
            Ub, Wb = Ua, Wa
        else:
            rb = kb.shape[2]
            Ub, Wb = self._whiten(kb.permute(1, 0, 2).reshape(p, N * rb), eps_reg)
            Ub, Wb = Ub.reshape(p, N, rb), Wb.reshape(p, N, rb)
        return torch.einsum("pni,pnj->nij", Ua, Ub) - torch.einsum("pni,pnj->nij", Wa, Wb)

    def _k0(self, x: Tensor) -> Tensor:
        """``K(x, X)`` by the expanded-square form (no ``(N, p, d)`` intermediate)."""
        return se_kernel(x, self.train_inputs, self.lengthscale, self.outputscale)

    # ------------------------------------------------------------------ means
    def mean(self, x: Tensor) -> Tensor:
        """``mu_f(x) = K(x, X) K^{-1} f_hat`` (paper Sec. 4). ``(d,)`` -> 0-d, ``(N, d)`` ->
        ``(N,)``. Differentiable in ``x``."""
        xb, single = _as_batch(x, self.dim)
        mu = self._k0(xb) @ self._alpha
        return mu[0] if single else mu

    def mean_gradient(self, x: Tensor) -> Tensor:
        """``mu_grad(x) = grad_x K(x, X) K^{-1} f_hat`` (paper Sec. 4). ``(d,)`` or ``(N, d)``."""
        xb, single = _as_batch(x, self.dim)
        _, k1 = kernel_derivatives(xb, self.train_inputs, self.lengthscale, self.outputscale, 1)
        g = torch.einsum("npd,p->nd", k1, self._alpha)
        return g[0] if single else g

    def mean_hessian(self, x: Tensor) -> Tensor:
        """``mu_hess(x) = hess_x K(x, X) K^{-1} f_hat`` (paper Sec. 4). ``(d, d)`` or
        ``(N, d, d)``; computed as ``R^T diag(alpha k) R - (sum_j alpha_j k_j) Lambda``."""
        xb, single = _as_batch(x, self.dim)
        inv_l2 = self.lengthscale.pow(-2)
        diff = xb.unsqueeze(-2) - self.train_inputs
        r = diff * inv_l2
        k0 = self.outputscale * torch.exp(-0.5 * (diff * r).sum(-1))
        wts = k0 * self._alpha  # (N, p)
        H = torch.einsum("np,npi,npj->nij", wts, r, r) - wts.sum(-1)[:, None, None] * torch.diag(
            inv_l2
        )
        return H[0] if single else H

    # ------------------------------------------------------------------ covariances
    def covariance_blocks(
        self, x: Tensor, orders: tuple[int, ...] = (0, 1, 2), eps_reg: float | None = None
    ) -> dict[str, Tensor]:
        """Blocks ``Sigma_ab`` of eq. (11) "general covariance block" for ``a <= b`` in ``orders``:

        ``Sigma_ab = L_a L_b' k(x, x')|_{x'=x} - k_a(x, X) (K + C_hat^{-1})^{-1} k_b(X, x)``.

        Keys ``"00"``, ``"01"``, ``"02"``, ``"11"``, ``"12"``, ``"22"``; for a ``(d,)`` input the
        blocks have shapes ``()``, ``(d,)``, ``(d^2,)``, ``(d, d)``, ``(d, d^2)``,
        ``(d^2, d^2)`` (Hessians vectorised row-major); a ``(N, d)`` input adds a leading N.
        ``Sigma_22`` costs ``O(p^2 d^2 + p d^4)``: request it only at moderate d.
        ``eps_reg`` overrides the fit's ``C_hat = C + eps_reg I`` (None = the fit's value).
        """
        xb, single = _as_batch(x, self.dim)
        orders = tuple(sorted(set(orders)))
        if not orders or any(o not in (0, 1, 2) for o in orders):
            raise ValueError(f"orders must be a non-empty subset of (0, 1, 2), got {orders}")
        N, d = xb.shape
        ks = kernel_derivatives(
            xb, self.train_inputs, self.lengthscale, self.outputscale, max(orders)
        )
        p = self.train_inputs.shape[0]
        flat = {0: ks[0].unsqueeze(-1)}
        if len(ks) > 1:
            flat[1] = ks[1]
        if len(ks) > 2:
            flat[2] = ks[2].reshape(N, p, d * d)
        out: dict[str, Tensor] = {}
        for i, a in enumerate(orders):
            for b in orders[i:]:
                prior = prior_block(a, b, self.lengthscale, self.outputscale)
                blk = prior - self._quad(flat[a], None if a == b else flat[b], eps_reg)
                if a == 0 and b == 0:
                    blk = blk[:, 0, 0]
                elif a == 0:
                    blk = blk[:, 0, :]
                out[f"{a}{b}"] = blk[0] if single else blk
        return out

    def variance(self, x: Tensor) -> Tensor:
        """Posterior variance ``Sigma_00(x)`` (eq. (11) "general covariance block"): 0-d or
        ``(N,)``."""
        return self.covariance_blocks(x, orders=(0,))["00"]

    def gradient_covariance(self, x: Tensor, eps_reg: float | None = None) -> Tensor:
        """``Sigma_11(x)`` of eq. (11) "general covariance block", the gradient covariance used by
        GIPBO (eq. (15) "pairwise-GP Jacobian variance"). ``(d, d)`` or ``(N, d, d)``."""
        return self.covariance_blocks(x, orders=(1,), eps_reg=eps_reg)["11"]

    def posterior_mean_cov(self, Xq: Tensor) -> tuple[Tensor, Tensor]:
        """Joint Laplace posterior of ``f`` at ``q`` points: mean ``(q,)`` and covariance
        ``K(Xq, Xq) - K(Xq, X) (K + C_hat^{-1})^{-1} K(X, Xq)`` ``(q, q)`` (eq.
        general_covariance_block with a = b = 0, off-diagonal). Differentiable in ``Xq``."""
        Xq, _ = _as_batch(Xq, self.dim, "Xq")
        kq = self._k0(Xq)
        mean = kq @ self._alpha
        prior = se_kernel_exact(Xq, Xq, self.lengthscale, self.outputscale)
        cov = prior - self._quad(kq.transpose(0, 1).unsqueeze(0))[0]
        return mean, cov

    def _difference(self, x: Tensor, x2: Tensor) -> tuple[Tensor, Tensor, bool]:
        """Posterior mean and ``2 + variance`` of ``f(x) - f(x2)`` (the probit noise added)."""
        xb, single = _as_batch(x, self.dim)
        x2b, single2 = _as_batch(x2, self.dim, "x2")
        if xb.shape != x2b.shape:
            raise ValueError(f"x and x2 must have the same shape, got {x.shape} and {x2.shape}")
        both = torch.stack([xb, x2b], dim=1)  # (N, 2, d)
        k = se_kernel(both, self.train_inputs, self.lengthscale, self.outputscale)
        mean = k @ self._alpha  # (N, 2)
        prior = se_kernel_exact(both, both, self.lengthscale, self.outputscale)
        cov = prior - self._quad(k.transpose(-1, -2))  # (N, 2, 2)
        var = 2.0 + cov[:, 0, 0] + cov[:, 1, 1] - 2.0 * cov[:, 0, 1]
        return mean[:, 0] - mean[:, 1], var.clamp_min(1e-300), single and single2

    def tie_probability(self, x: Tensor, x2: Tensor) -> Tensor:
        """``P(x ~ x2)`` ("can't tell") of the ordinal model (:mod:`.ordinal`) marginalised
        over the Gaussian posterior of ``g = f(x) - f(x2)``:
        ``Phi((eps - mu_g) / s) - Phi((-eps - mu_g) / s)``, ``s^2 = 2 + var_g``; zero at
        ``tie_threshold = 0``. Shapes as :meth:`preference_probability`."""
        mu, var, single = self._difference(x, x2)
        sd = var.sqrt()
        eps = self.tie_threshold
        prob = torch.special.ndtr((eps - mu) / sd) - torch.special.ndtr((-eps - mu) / sd)
        prob = prob.clamp_min(0.0)
        return prob[0] if single else prob

    def preference_probability(self, x: Tensor, x2: Tensor) -> Tensor:
        """``P(x > x2)`` under the Laplace posterior with probit noise sigma_n = 1 (eq.
        likelihood marginalised over the Gaussian posterior):
        ``Phi((mu1 - mu2 - eps) / sqrt(2 + var1 + var2 - 2 cov12))`` with the indifference
        threshold ``eps = tie_threshold`` (0: the paper's eq.). 0-d for ``(d,)`` inputs,
        ``(N,)`` for ``(N, d)`` inputs (pairwise rows)."""
        mu, var, single = self._difference(x, x2)
        prob = torch.special.ndtr((mu - self.tie_threshold) / var.sqrt())
        return prob[0] if single else prob

    # ------------------------------------------------------------------ sampling
    def sample_paths(
        self, num_paths: int, generator: torch.Generator, num_features: int = 1024
    ) -> SamplePaths:
        """Posterior sample paths (see :mod:`.sampling`): a callable ``(N, d) -> (N, num_paths)``
        differentiable in its input, with closed-form input gradients
        (:meth:`SamplePaths.value_and_grad`), deterministic given ``generator``."""
        from .sampling import draw_sample_paths

        return draw_sample_paths(self, num_paths, generator, num_features)

    # accessors for sampling.py
    @property
    def chol_K(self) -> Tensor:
        """Cholesky factor ``L`` of ``K + jitter`` at the training points."""
        return self._L

    @property
    def chol_B(self) -> Tensor:
        """Cholesky factor of ``B = I + L^T C_hat L``."""
        return self._LB
