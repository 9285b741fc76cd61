"""Maximum likelihood for the gamma GLMM: Laplace approximation and adaptive Gauss-Hermite quadrature.

The random intercept enters each participant's likelihood as a one-dimensional integral

``L_i = int prod_j Gamma(y_ij; shape nu, mean exp(eta_ij + b)) N(b; 0, sigma_b^2) db``,

approximated around the conditional mode ``b_i`` with curvature ``H_i = -g_i''(b_i)`` by adaptive
Gauss-Hermite quadrature (Liu & Pierce 1994, Biometrika 81:624; Pinheiro & Bates 1995, J Comput Graph
Stat 4:12): ``L_i ~ sqrt(2) s_i sum_k w_k exp(x_k^2) exp(g_i(b_i + sqrt(2) s_i x_k))``, ``s_i = H_i^-1/2``.
One node is the Laplace approximation (what glmmTMB maximises). For the gamma/log model the
mode equation ``nu (A_i e^-b - n_i) = b / sigma_b^2`` (``A_i = sum_j y_ij e^-eta_ij``) has a concave
log-integrand, so Newton's method finds it for all participants at once.

The gradient below is exact (implicit differentiation of the mode and curvature); the Hessian used for
the standard errors is the central difference of that gradient, as TMB/glmmTMB do for theirs.
Parameters: ``theta = (beta, log sigma_b, log phi)`` with ``phi = 1 / nu``.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy import optimize, special

from bowden.errors import FitError
from bowden.stats.design import Design, FloatArray
from bowden.stats.glmm_result import GlmmOptions, GlmmResult, glmm_result


@dataclass(frozen=True)
class _Data:
    x: FloatArray
    y: FloatArray
    group: np.ndarray
    n: FloatArray  # rows per participant
    xs: FloatArray  # sum of x rows per participant (m, p)
    log_y: FloatArray  # sum of log y per participant


class MarginalLikelihood:
    """Log-likelihood of the gamma GLMM, and its gradient, by adaptive Gauss-Hermite quadrature.

    Parameters
    ----------
    design:
        The model design.
    n_nodes:
        Quadrature nodes per participant (1: Laplace).
    """

    def __init__(self, design: Design, n_nodes: int) -> None:
        m = design.n_participants
        xs = np.zeros((m, design.x.shape[1]))
        np.add.at(xs, design.group, design.x)
        self._d = _Data(
            x=design.x,
            y=design.y,
            group=design.group,
            n=np.bincount(design.group, minlength=m).astype(float),
            xs=xs,
            log_y=np.asarray(np.bincount(design.group, weights=np.log(design.y), minlength=m), dtype=float),
        )
        nodes, weights = np.polynomial.hermite.hermgauss(n_nodes)
        self._nodes = nodes
        self._log_w = np.log(weights) + nodes**2
        self.p = design.x.shape[1]
        self._modes = np.zeros(m)

    def _pieces(self, theta: FloatArray) -> dict[str, FloatArray | float]:
        d = self._d
        beta, tau, omega = theta[: self.p], float(theta[self.p]), float(theta[self.p + 1])
        nu = np.exp(-omega)
        var_b = np.exp(2.0 * tau)
        eta = d.x @ beta
        e = d.y * np.exp(-eta)
        m = d.n.size
        a = np.asarray(np.bincount(d.group, weights=e, minlength=m), dtype=float)
        s = np.zeros((m, self.p))
        np.add.at(s, d.group, d.x * e[:, None])
        eta_sum = np.bincount(d.group, weights=eta, minlength=m)
        mode = self._mode(a, nu, var_b)
        curvature = nu * a * np.exp(-mode) + 1.0 / var_b
        return {
            "nu": nu,
            "var_b": var_b,
            "tau": tau,
            "a": a,
            "s": s,
            "eta_sum": eta_sum,
            "mode": mode,
            "curvature": curvature,
        }

    def _mode(self, a: FloatArray, nu: float, var_b: float) -> FloatArray:
        n = self._d.n
        # Start from the mode without the prior (log(A/n)) shrunk, or from the previous call's modes.
        b = np.where(np.isfinite(self._modes), self._modes, np.log(a / n))
        for _ in range(200):
            grad = nu * (a * np.exp(-b) - n) - b / var_b
            hess = -nu * a * np.exp(-b) - 1.0 / var_b
            step = grad / hess
            b = b - step
            if float(np.max(np.abs(step))) < 1e-13 * max(1.0, float(np.max(np.abs(b)))):
                self._modes = b
                return b
        raise FitError("the conditional modes of the random intercepts did not converge")

    def _log_integrand(self, b: FloatArray, pc: dict[str, FloatArray | float]) -> FloatArray:
        """g_i(b) for every participant (rows) and node (columns)."""
        d = self._d
        nu, var_b, tau = float(pc["nu"]), float(pc["var_b"]), float(pc["tau"])
        n = d.n[:, None]
        cond = (
            n * (nu * np.log(nu) - special.gammaln(nu))
            - nu * (np.asarray(pc["eta_sum"])[:, None] + n * b)
            + (nu - 1.0) * d.log_y[:, None]
            - nu * np.asarray(pc["a"])[:, None] * np.exp(-b)
        )
        return np.asarray(cond - b**2 / (2.0 * var_b) - 0.5 * np.log(2.0 * np.pi) - tau)

    def loglik(self, theta: FloatArray) -> float:
        """Marginal log-likelihood at ``theta = (beta, log sigma_b, log phi)``."""
        pc = self._pieces(theta)
        scale = 1.0 / np.sqrt(np.asarray(pc["curvature"]))
        points = np.asarray(pc["mode"])[:, None] + np.sqrt(2.0) * scale[:, None] * self._nodes[None, :]
        terms = self._log_w[None, :] + self._log_integrand(points, pc)
        per = 0.5 * np.log(2.0) + np.log(scale) + special.logsumexp(terms, axis=1)
        return float(np.sum(per))

    def gradient(self, theta: FloatArray) -> FloatArray:
        """Exact gradient of :meth:`loglik` (implicit differentiation through mode and curvature)."""
        d = self._d
        pc = self._pieces(theta)
        nu, var_b = float(pc["nu"]), float(pc["var_b"])
        a, s = np.asarray(pc["a"]), np.asarray(pc["s"])
        mode, curv = np.asarray(pc["mode"]), np.asarray(pc["curvature"])
        scale = 1.0 / np.sqrt(curv)
        points = mode[:, None] + np.sqrt(2.0) * scale[:, None] * self._nodes[None, :]
        terms = self._log_w[None, :] + self._log_integrand(points, pc)
        post = np.exp(terms - special.logsumexp(terms, axis=1, keepdims=True))  # normalised node weights
        em = np.exp(-mode)
        ek = np.exp(-points)
        n = d.n
        g1 = nu * (a[:, None] * ek - n[:, None]) - points / var_b  # g'(b_k)
        h_b = -nu * a * em  # dH/db at the mode
        sqrt2x = np.sqrt(2.0) * self._nodes[None, :] * scale[:, None]

        def total(dg_nodes: FloatArray, dgp: FloatArray, dh: FloatArray) -> FloatArray:
            """d log L_i for one parameter: partials of g (per node), of g' and of H at the mode."""
            db = dgp / curv
            dh_tot = dh + h_b * db
            dlog_s = -0.5 * dh_tot / curv
            return np.asarray(
                dlog_s + np.sum(post * (dg_nodes + g1 * (db[:, None] + sqrt2x * dlog_s[:, None])), axis=1)
            )

        grad = np.empty(self.p + 2)
        # beta: dg/dbeta(b) = nu (S e^-b - xs); dg'/dbeta = dH/dbeta = -nu e^-b S.
        wk = np.sum(post * ek, axis=1)  # sum_k pi_k e^{-b_k}
        dgp_beta = -nu * em[:, None] * s
        db_beta = dgp_beta / curv[:, None]
        dh_tot_beta = dgp_beta + h_b[:, None] * db_beta
        dlog_s_beta = -0.5 * dh_tot_beta / curv[:, None]
        g1_post = np.sum(post * g1, axis=1)
        g1x_post = np.sum(post * g1 * sqrt2x, axis=1)
        per_beta = (
            dlog_s_beta
            + nu * (s * wk[:, None] - d.xs)
            + g1_post[:, None] * db_beta
            + g1x_post[:, None] * dlog_s_beta
        )
        grad[: self.p] = per_beta.sum(axis=0)
        # log sigma_b: dg/dtau = b^2/var_b - 1; dg'/dtau = 2 b / var_b; dH/dtau = -2 / var_b.
        grad[self.p] = np.sum(
            total(points**2 / var_b - 1.0, 2.0 * mode / var_b, np.full_like(mode, -2.0 / var_b))
        )
        # log phi (nu = e^-omega): dg/domega = -nu dg/dnu; dg'/domega = -nu (A e^-b - n);
        # dH/domega = -nu A e^-b.
        dg_dnu = (
            n[:, None] * (np.log(nu) + 1.0 - special.digamma(nu))
            - (np.asarray(pc["eta_sum"])[:, None] + n[:, None] * points)
            + d.log_y[:, None]
            - a[:, None] * ek
        )
        grad[self.p + 1] = np.sum(total(-nu * dg_dnu, -nu * (a * em - n), -nu * a * em))
        return grad

    @property
    def modes(self) -> FloatArray:
        """Conditional modes of the random intercepts at the last evaluation."""
        return self._modes.copy()


def hessian_of_gradient(
    grad: Callable[[FloatArray], FloatArray], theta: FloatArray, rel_step: float = 1e-5
) -> FloatArray:
    """Symmetrised central-difference Jacobian of a gradient function."""
    fn = grad
    k = theta.size
    hess = np.empty((k, k))
    for j in range(k):
        h = rel_step * max(1.0, abs(float(theta[j])))
        up, down = theta.copy(), theta.copy()
        up[j] += h
        down[j] -= h
        hess[:, j] = (fn(up) - fn(down)) / (2.0 * h)
    return 0.5 * (hess + hess.T)


def fit_marginal_ml(design: Design, start: GlmmResult, *, n_nodes: int, options: GlmmOptions) -> GlmmResult:
    """Maximise the marginal likelihood from the PQL estimates ``start`` (Newton with line search).

    Raises
    ------
    FitError
        Newton and the BFGS fallback both fail to reach a stationary point.
    """
    model = MarginalLikelihood(design, n_nodes)
    model._modes = start.random_effects.to_numpy().copy()
    theta = np.concatenate(
        (start.coef.to_numpy(), [0.5 * np.log(max(start.participant_var, 1e-8)), np.log(start.dispersion)])
    )
    value = model.loglik(theta)
    converged = False
    iteration = 0
    step_norm = np.inf
    for iteration in range(1, options.max_iterations + 1):  # noqa: B007 - reported after the loop
        grad = model.gradient(theta)
        hess = hessian_of_gradient(model.gradient, theta)
        try:
            step = -np.linalg.solve(hess, grad)
        except np.linalg.LinAlgError:
            step = grad  # plain ascent when the Hessian is singular
        if grad @ step <= 0.0:
            step = grad / max(1.0, float(np.max(np.abs(grad))))  # not an ascent direction: use the gradient
        factor = 1.0
        while factor > 1e-8:
            candidate = theta + factor * step
            cand_value = model.loglik(candidate)
            if np.isfinite(cand_value) and cand_value >= value - 1e-12 * abs(value):
                break
            factor *= 0.5
        else:
            break
        step_norm = float(np.max(np.abs(factor * step)))
        theta, value = candidate, cand_value
        if step_norm < 1e-9:
            converged = True
            break
    if not converged:
        res = optimize.minimize(
            lambda t: -model.loglik(t),
            theta,
            jac=lambda t: -model.gradient(t),
            method="BFGS",
            options={"gtol": 1e-9, "maxiter": 10 * options.max_iterations},
        )
        theta = np.asarray(res.x)
        step_norm = float(np.max(np.abs(model.gradient(theta))))
        converged = step_norm < 1e-5
        if not converged:
            raise FitError(
                f"maximum likelihood ({'Laplace' if n_nodes == 1 else f'{n_nodes}-node AGQ'}) did not "
                f"converge (largest gradient component {step_norm:.3g}); the participant variance may be "
                "near zero: try method='pql-reml'"
            )
    hess = hessian_of_gradient(model.gradient, theta)
    try:
        cov = np.asarray(np.linalg.inv(-hess), dtype=float)
    except np.linalg.LinAlgError as exc:
        raise FitError("the Hessian of the marginal likelihood is singular at the optimum") from exc
    if not np.all(np.diag(cov) > 0.0):
        raise FitError("the marginal likelihood has no maximum here (Hessian not negative definite)")
    p = design.x.shape[1]
    model.loglik(theta)  # leaves the conditional modes of the final estimates in model.modes
    return glmm_result(
        design,
        "laplace" if n_nodes == 1 else f"agq{n_nodes}",
        theta[:p],
        cov[:p, :p],
        float(np.exp(2.0 * theta[p])),
        float(np.exp(theta[p + 1])),
        model.modes,
        model.loglik(theta),
        iteration,
        step_norm,
    )
