"""Build (or load from the disk cache) a CasADi SQP solver and call it through Function.buffer().

Chosen by measurement on OP3 (numbers in the package docstring):

- ``sqpmethod`` with the **exact Hessian**, convexified by reflecting negative eigenvalues, for
  one frame (online): it converges in ≈ 4 iterations even for unreachable targets.
- ``sqpmethod`` with a **Gauss–Newton Hessian** 2·JᵀJ of the weighted residuals (passed as
  ``hess_lag``, PSD by construction) for windows (offline), where eigen-clipping a W·J Hessian
  is too slow.
- QP solvers: ``daqp`` (dense active set, ``primal_tol`` 1e-9) for one frame; ``osqp`` (sparse
  ADMM) for windows, where dense QPs grow cubically and ``qrqp`` needs many active-set steps
  when velocity limits bind. Every result is projected and checked afterwards anyway.
- JIT: the NLP's functions are compiled once with the system C compiler (``-O1``) into a shared
  library in the cache directory (``$ROBOT_RETARGET_CACHE`` or ``~/.cache/robot_retarget``);
  the serialized solver links it and is keyed by a hash of the exact expressions, options and
  casadi version. Without a working compiler the same solver runs interpreted (≈ 4× slower),
  with a logged warning.
- Calls go through ``Function.buffer()`` (:class:`robot_retarget.casadi_jit.CompiledFunction`):
  arguments and results are numpy arrays bound once, so a solve costs no Python marshalling.
  The buffer and arrays must stay referenced: they do, as attributes of :class:`BufferedSolver`.
- A solve that does not converge raises (``error_on_fail``), and that is how a call learns it
  failed: casadi's ``stats()``, the other way to learn it, builds a Python dict of ~30 entries
  and took 15–50 µs per frame in the live path (OP3's step, alternating in one process:
  0.397 → 0.354 ms without it). The iteration count and status text are read only when asked
  (:meth:`BufferedSolver.last_status`): after a failed solve, or for an offline window.
"""

from __future__ import annotations

import hashlib
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import casadi as ca

from robot_retarget.casadi_jit import CompiledFunction, default_cache_dir, load_or_jit

MIN_STEP_FLOOR = 1e-12  # the smallest SQP step that still counts as progress (rad)


@dataclass(frozen=True)
class SolverSpec:
    """Everything that defines one solver (and its cache key)."""

    name: str
    qpsol: str  # "daqp" or "qrqp"
    max_iter: int
    jit: bool
    hessian: str = "gauss-newton"  # or "exact" (convexified by eigenvalue reflection)
    tol_pr: float = 1e-9  # primal infeasibility at convergence (rad / m)
    tol_du: float = 1e-7  # dual infeasibility (stationarity) at convergence
    # The SQP stops when a step's largest joint move is at most this (rad, never below
    # MIN_STEP_FLOOR); casadi then reports "Search_Direction_Becomes_Too_Small" (STEP_TOL_STATUS).
    min_step: float = 0.0
    compiler: str | None = None  # None: gcc or cc from PATH
    cache_dir: Path | None = None  # None: default_cache_dir()


def _qp_options(qpsol: str) -> dict[str, Any]:
    if qpsol == "daqp":
        # daqp's default primal tolerance once let a velocity bound slip by 8e-4 rad.
        return {"error_on_fail": False, "daqp": {"primal_tol": 1e-9}}
    if qpsol == "qrqp":
        return {
            "error_on_fail": False,
            "print_iter": False,
            "print_header": False,
            "print_info": False,
            "constr_viol_tol": 1e-9,
            "dual_inf_tol": 1e-9,
        }
    if qpsol == "osqp":
        return {
            "error_on_fail": False,
            "warm_start_primal": True,
            "osqp": {
                "verbose": False,
                "eps_abs": 1e-7,
                "eps_rel": 1e-7,
                "polish": False,
                "max_iter": 4000,
            },
        }
    raise ValueError(f"unsupported QP solver {qpsol!r}; use 'daqp', 'qrqp' or 'osqp'")


def _options(spec: SolverSpec) -> dict[str, Any]:
    extra: dict[str, Any] = (
        # Reflect (|λ|), not clip: clipped directions have no curvature, so a far target made
        # the step run to the joint limits and Poppy's 5-joint spine needed > 20 iterations.
        # casadi's default of 200 eigen-solver sweeps fails ("Failure in convexification") on
        # Hessians of ≥ 60 variables (casadi issue #2973); sweeps stop at convergence.
        {"convexify_strategy": "eigen-reflect", "convexify_margin": 1e-7, "max_iter_eig": 100000}
        if spec.hessian == "exact"
        else {}
    )
    return {
        **extra,
        "qpsol": spec.qpsol,
        "qpsol_options": _qp_options(spec.qpsol),
        "max_iter": spec.max_iter,
        "tol_pr": spec.tol_pr,
        "tol_du": spec.tol_du,
        "min_step_size": max(spec.min_step, MIN_STEP_FLOOR),
        "print_header": False,
        "print_iteration": False,
        "print_status": False,
        "print_time": False,
        # A failed solve raises, with its iterate written: BufferedSolver.call's verdict.
        "error_on_fail": True,
        "calc_lam_p": False,  # unused, and NaN where a weight is 0 (d√w/dw)
    }


def _gauss_newton_hessian(nlp: dict[str, ca.SX]) -> ca.Function:
    x, p, r = nlp["x"], nlp["p"], nlp["r"]
    lam_f = ca.SX.sym("lam_f")
    lam_g = ca.SX.sym("lam_g", nlp["g"].shape[0])
    jac = ca.jacobian(r, x)
    hess = 2.0 * lam_f * ca.mtimes(jac.T, jac)
    return ca.Function(
        "nlp_hess_l", [x, p, lam_f, lam_g], [hess], ["x", "p", "lam_f", "lam_g"], ["hess_gamma_x_x"]
    )


def cache_key(spec: SolverSpec, nlp: dict[str, ca.SX]) -> str:
    """Hash of the exact expressions, the options and the casadi version."""
    fn = ca.Function("nlp", [nlp["x"], nlp["p"]], [nlp["f"], nlp["g"], nlp["r"]])
    h = hashlib.sha256()
    h.update(fn.serialize().encode())
    h.update(repr(sorted(_options(spec).items())).encode())
    h.update(str(ca.CasadiMeta.version()).encode())
    return h.hexdigest()[:20]


def build_solver(spec: SolverSpec, nlp: dict[str, ca.SX]) -> tuple[ca.Function, bool]:
    """(solver, jit_used). Loads a cached JIT build, compiles one, or falls back to no JIT."""
    problem = {k: nlp[k] for k in ("x", "p", "f", "g")}
    opts = _options(spec)
    if spec.jit:
        cache = spec.cache_dir or default_cache_dir()
        compiled = load_or_jit(
            cache / f"{spec.name}-{cache_key(spec, nlp)}.casadi",
            lambda jit: ca.nlpsol(
                spec.name, "sqpmethod", problem, {**opts, **jit, **_hessian(spec, nlp)}
            ),
            without="the retargeting solver runs without JIT, about 2x slower",
            compiler=spec.compiler,
        )
        if compiled is not None:
            return compiled, True
    solver = ca.nlpsol(spec.name, "sqpmethod", problem, {**opts, **_hessian(spec, nlp)})
    return solver, False


def _hessian(spec: SolverSpec, nlp: dict[str, ca.SX]) -> dict[str, Any]:
    if spec.hessian == "gauss-newton":
        return {"hess_lag": _gauss_newton_hessian(nlp)}
    if spec.hessian == "exact":
        return {}
    raise ValueError(f"unknown Hessian {spec.hessian!r}; use 'gauss-newton' or 'exact'")


# casadi's status for a solve stopped by ``SolverSpec.min_step``.
STEP_TOL_STATUS = "Search_Direction_Becomes_Too_Small"
MAX_ITER_STATUS = "Maximum_Iterations_Exceeded"
# The two ways a solve stops short that leave a usable iterate; any other status (NaN in a
# derivative, "Non_Regular_Sensitivities", a failed QP) is a solve that failed.
STOPPED_SHORT = frozenset({STEP_TOL_STATUS, MAX_ITER_STATUS})

# What casadi raises (with the iterate written) when an nlpsol with ``error_on_fail`` stops
# without converging; any other error is not a verdict on the solve and propagates.
_NOT_CONVERGED = "nlpsol process failed"


class BufferedSolver:
    """A solver bound to numpy arrays once; ``call()`` solves in place."""

    def __init__(self, solver: ca.Function, jit_used: bool) -> None:
        self.solver = solver
        self.jit_used = jit_used
        bound = CompiledFunction(solver)
        self.args, self.res = bound.args, bound.res
        names_in = solver.name_in()
        names_out = solver.name_out()
        self.x0, self.p, self.lbx, self.ubx, self.lbg, self.ubg, self.lam_x0, self.lam_g0 = (
            self.args[names_in.index(n)]
            for n in ("x0", "p", "lbx", "ubx", "lbg", "ubg", "lam_x0", "lam_g0")
        )
        self.x, self.f, self.g, self.lam_x, self.lam_g = (
            self.res[names_out.index(n)] for n in ("x", "f", "g", "lam_x", "lam_g")
        )
        self._trigger: Callable[[], None] = bound

    def call(self) -> bool:
        """Solve in place; whether the SQP converged. Its iterate, multipliers and cost are in
        the result arrays either way (a solve stopped at ``max_iter`` leaves its last iterate).
        """
        try:
            self._trigger()
        except RuntimeError as exc:
            # A Ctrl-C during the solve: casadi runs Python's SIGINT handler from inside the
            # call and hands its KeyboardInterrupt back as a RuntimeError. Raise it as what it
            # was, so the control loop's smooth stop (and anything else) sees a Ctrl-C.
            if "KeyboardInterrupt" in str(exc):
                raise KeyboardInterrupt from exc
            if _NOT_CONVERGED in str(exc):  # the status says why (last_status)
                return False
            raise
        return True

    def last_status(self) -> tuple[int, str]:
        """(SQP iterations, casadi's return status) of the last :meth:`call`: read from
        casadi's statistics, 15–50 µs, so only when wanted."""
        try:
            # The buffer evaluates in memory slot 1 (slot 0 belongs to plain calls).
            stats = self.solver.stats(1)
        except RuntimeError as exc:  # casadi cannot even name the status: a hard failure
            return 0, f"solver failed ({exc})"
        return int(stats["iter_count"]), str(stats["return_status"])
