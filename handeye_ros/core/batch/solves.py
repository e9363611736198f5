"""The solve of stage 3 (eq. 15-16): (dt, T_HE) on the eye residuals with the spline held to
the MoCap.

It runs in two passes when a noise is estimated (the noise is measured again at the first
solution) and, ``decoupled``, in two steps: the rotation first, then the translation.
:mod:`.batch.refine` turns the answer into a :class:`BatchSolution`.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from functools import partial

import numpy as np

from ..arrays import Floats, Indices
from .covariance import CovarianceSums, eye_covariance
from .levenberg_marquardt import (
    NormalSums,
    SolverReport,
    SumsOfChunks,
    levenberg_marquardt_dense,
)
from .long_run import LongRunCovariance
from .loss import huber_cost
from .noise import Noise, sigmas
from .options import BatchOptions
from .parameters import ParameterLayout, weighted_eye_chunks
from .residuals import BatchProblem, Weights

#: Chunks of eye pairs the first of the two noise passes uses on a long recording (spread
#: over it); the second pass and the covariance use every pair.
FIRST_PASS_CHUNKS = 4


@dataclass(frozen=True)
class Solve:
    """What the solve hands back to :func:`.batch.refine.refine`.

    x: the solution y;
    weights: the final 1/sigma of each stream; covariance: white, (n_y, n_y) in the order of
    y (zero rows for entries held fixed); long_run: the reported covariance
    (:mod:`.batch.long_run`); n_residuals, n_free: for the reduced chi^2; report: the last
    solver run's.
    """

    x: Floats
    cost_before: float
    cost_after: float
    hand_noise: Noise
    eye_noise: Noise
    weights: Weights
    covariance: Floats
    long_run: LongRunCovariance
    n_residuals: int
    n_free: int
    report: SolverReport


def solve_offset_extrinsic(
    prob: BatchProblem, layout: ParameterLayout, hand_noise: Noise, o: BatchOptions
) -> Solve:
    """(dt, T_HE) by Huber Levenberg-Marquardt on the eye residuals, the spline fixed to the
    hand, with the analytic Jacobian of :meth:`.batch.residuals.BatchProblem.eye_chunk`
    (:func:`.batch.levenberg_marquardt.levenberg_marquardt_dense`). Parameters y = (dt, dtheta_X, dp_X, ...)
    from the start values.

    ``decoupled``: first (dt, dtheta_X) on the rotation residuals alone, then (dt, dp_X) on
    all residuals with the rotation fixed: a VIO's relative translations carry errors that are
    not white (scale, drift), and in one solve of all together they pull the extrinsic's
    rotation (docs/method.md, "Decoupled batch solve").

    Two passes: the eye noise is measured at the linear result, then again at the first
    solution (the linear result's residuals include its own error). ``o``: the eye's noise
    (None: measured), the Huber delta, the iterations, ``decoupled``.
    """
    eye_noise, delta, decoupled = o.eye_noise, o.huber_delta, o.decoupled
    y: Floats = np.zeros(layout.size)
    r_start = prob.eye_raw(y)  # kept: the cost before, at the final weights
    en = Noise(*sigmas(r_start, eye_noise))
    passes = 2 if en.estimated else 1
    steps = [(layout.a, True), (layout.b, False)] if decoupled else [(layout.all, False)]
    for k in range(passes):
        # the hand's weights are not used: the spline is held to the MoCap fit
        weights = Weights(eye_rotation=1.0 / en.rotation, eye_translation=1.0 / en.translation)
        # the first pass only has to get near enough to measure the noise again: one
        # Gauss-Newton step from the linear result does, on a long recording from
        # FIRST_PASS_CHUNKS chunks spread over it (some 130 000 pairs)
        last_pass = k + 1 == passes
        y, report, last = _noise_pass(
            prob,
            y,
            steps,
            _SweepPlan(
                weights,
                delta=delta,
                every=1 if last_pass else max(1, len(prob.chunks()) // FIRST_PASS_CHUNKS),
                covariance=(layout, decoupled) if last_pass else None,
                keep_raw=not last_pass,
            ),
            o.max_iterations if last_pass else 1,
        )
        if not last_pass:
            # the last step's sweep kept the residuals at y, unless it took no step from the
            # sums the step before handed it (its start already solved: exact data)
            raw = last.raw if last.raw is not None else prob.eye_raw(y)
            en = Noise(*sigmas(raw, eye_noise))
    cost_before = huber_cost((r_start * weights.eye).ravel(), delta)
    del r_start
    # the covariance as the last sweep gathered it at y, or (when the last step took no step
    # from the sums it was handed) from a sweep of its own
    same = _same_sweep(last)
    if same is not None and same.covariance is not None:
        cov, lr, cost_after, n_res = same.covariance.result()
    else:
        cov, lr, cost_after, n_res = eye_covariance(prob, weights, y, layout, delta, decoupled)
    n = layout.all.size
    return Solve(y, cost_before, cost_after, hand_noise, en, weights, cov, lr, n_res, n, report)


def _noise_pass(
    prob: BatchProblem,
    y: Floats,
    steps: list[tuple[Indices, bool]],
    plan: _SweepPlan,
    iterations: int,
) -> tuple[Floats, SolverReport, NormalSums]:
    """One of :func:`solve_offset_extrinsic`'s two passes (one per noise estimate): its steps
    (free parameters, rotation rows only) solved in turn from y, each evaluation a sweep over
    the eye pairs (:func:`_sweep`). ``plan``: the pass's weights, chunks and what its last
    step's sweeps gather (the covariance, or the residuals for the next noise estimate).
    Returns the last step's (y, report, sums at y)."""
    start = None
    for s, (free, rotation_only) in enumerate(steps):
        final = s + 1 == len(steps)
        # the rotation step's sweeps sum the translation step's start on the same residuals;
        # the last step's gather what the plan asks (at the solution: the last of them)
        step_plan = replace(
            plan,
            free=free,
            rotation_only=rotation_only,
            then=None if final else steps[s + 1][0],
            covariance=plan.covariance if final else None,
            keep_raw=plan.keep_raw and final,
        )
        y, report, last = levenberg_marquardt_dense(
            partial(_sweep, prob, plan=step_plan), y, free, iterations, start
        )
        start = None if (same := _same_sweep(last)) is None else same.then
    return y, report, last


@dataclass(frozen=True)
class _SweepPlan:
    """What one sweep of the default solve over the eye pairs sums (:func:`_sweep`): the
    step's normal sums (its free parameters; the rotation rows alone when ``rotation_only``)
    and, on the same residuals, the next step's (``then``: its free parameters, all rows),
    the covariance's (``covariance``: its layout and whether decoupled) and the unweighted
    residuals (``keep_raw``)."""

    weights: Weights
    delta: float
    every: int = 1
    free: Indices | None = None
    rotation_only: bool = False
    then: Indices | None = None
    covariance: tuple[ParameterLayout, bool] | None = None
    keep_raw: bool = False


@dataclass(frozen=True)
class _SameSweep:
    """What a sweep gathered beside its step's sums: the next step's sums and the
    covariance's, at the same y."""

    then: NormalSums | None
    covariance: CovarianceSums | None


def _same_sweep(sums: NormalSums) -> _SameSweep | None:
    """What the sweep of :func:`_sweep` gathered beside ``sums`` (None: nothing)."""
    return sums.extra if isinstance(sums.extra, _SameSweep) else None


def _sweep(prob: BatchProblem, y: Floats, plan: _SweepPlan) -> NormalSums:
    """One sweep over the eye pairs at y (every ``plan.every``-th chunk), summed as
    :class:`_SweepPlan` says."""
    full_rows = not plan.rotation_only or plan.then is not None
    assert plan.free is not None, 'a sweep sums over free parameters'
    step = SumsOfChunks(plan.free, plan.delta)
    then = None if plan.then is None else SumsOfChunks(plan.then, plan.delta)
    cov = None
    if plan.covariance is not None:
        layout, decoupled = plan.covariance
        cov = CovarianceSums(layout, plan.delta, decoupled)
    raw: list[Floats] | None = [] if plan.keep_raw else None
    rows = 3 if plan.rotation_only else 6
    for r, J in weighted_eye_chunks(prob, plan.weights, y, not full_rows, raw, plan.every):
        step.add(r[:, :rows], J[:, :rows])
        for more in (then, cov):
            if more is not None:
                more.add(r, J)
    extra = (
        None
        if then is None and cov is None
        else _SameSweep(None if then is None else then.sums(), cov)
    )
    return step.sums(None if raw is None else np.concatenate(raw), extra)
