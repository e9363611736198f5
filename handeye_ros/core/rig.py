"""One rig, many recordings: one extrinsic T_HE shared by all, each recording its own clock.

Beyond the paper, which calibrates one recording. A rig (one marker on one device) recorded
several times has one T_HE; each recording has its own offset dt (and drift, scale) and its own
worlds. The batch stage (Section III-C) of each recording leaves its estimate and covariance
``C_i`` over (dt, translation, rotation[, drift][, scale]) (:class:`.batch.refine.BatchSolution`).
Eliminating a recording's own parameters from its normal equations (the Schur complement over
them) leaves, for the shared x = T_HE, the reduced system ``Lambda_i = (C_i[x, x])^-1`` about its
own estimate ``x_i``. The joint T_HE minimises the sum of those reduced costs (eq. 16 summed over
the recordings, to first order about each recording's solution):

    x* = argmin_x  sum_i  (x_i [-] x)^T Lambda_i (x_i [-] x),     Cov(x*) = (sum_i Lambda_i)^-1

and each recording's own parameters follow by back-substitution, the Gaussian conditioning of
``C_i`` on x* (:func:`conditioned`). So a process needs only each recording's 7x7 (or 9x9)
covariance, never its poses: that is how many recordings run on a cluster.

Tangents are the batch stage's: x [-] y = (p_x - p_y, Log(R_y^T R_x)), translation [m] in the
hand frame, rotation [rad] on the right (eye frame), in that order.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from .arrays import Floats
from .batch.rank import ROUNDING_RTOL, pseudo_inverse, solve_determined, undetermined
from .document import ResultDoc
from .geometry import difference, exp_so3, matrix_from_quat, quat_from_matrix
from .rig_document import MemberDoc

#: Index of T_HE (translation, rotation) in a batch covariance (dt first).
EXTRINSIC = slice(1, 7)
#: Gauss-Newton rounds of the joint mean; it converges in 2-3 (the estimates differ by mm).
MAX_ROUNDS = 20
STEP_TOL = 1e-12
#: Held directions of two estimates that are parallel to within this (the singular values of
#: their stacked unit bases) are one direction.
RANK_SPAN = 1e-6
#: A held unit direction of T_HE whose translation or rotation part is below this has none of
#: that part (a lever arm held alone, or a rotation).
HELD_PART = 1e-6


@dataclass(frozen=True)
class Member:
    """One recording's own calibration, as the rig uses it.

    time_offset_s: dt [s]; q_HE (x y z w), p_HE [m]: its own T_HE; covariance: its batch
    covariance in ``order`` (time_offset, tx, ty, tz, rx, ry, rz[, clock_drift][, scale]);
    values: the estimates in the same order where they are not T_HE (dt, drift, scale);
    precision: the 1-sigmas its calibration required of T_HE (translation [m], rotation [deg];
    its options ``precision_translation``, ``precision_rotation``), None when not known.
    """

    name: str
    q_HE: Floats
    p_HE: Floats
    covariance: Floats
    order: tuple[str, ...]
    values: dict[str, float]
    precision: tuple[float, float] | None = None

    @property
    def holds_rotation(self) -> bool:
        """Its covariance holds a direction of T_HE's rotation (a rig turned in place about one
        axis: the rotation about it set, not measured, and the translation across it with
        it). Such an estimate is no linear measurement of T_HE along the held rotation, so it
        is not tested nor fused: it follows a rig."""
        held = undetermined(self.extrinsic_covariance)
        return bool(np.any(np.linalg.norm(held[3:], axis=0) > HELD_PART))

    @property
    def extrinsic_covariance(self) -> Floats:
        """Its T_HE's 6x6 marginal (translation, rotation): the Schur complement of its
        information over its own parameters, inverted."""
        return self.covariance[EXTRINSIC, EXTRINSIC]

    @classmethod
    def from_document(cls, name: str, doc: ResultDoc) -> Member:
        """Of a result document (:meth:`.result.CalibrationResult.to_dict`); ValueError when
        it has no covariance (no batch stage) or one that is not positive definite."""
        cov = doc.get('covariance')
        if not cov:
            raise ValueError('it has no covariance (the batch stage did not run)')
        C = np.asarray(cov['matrix'], dtype=float)
        order = tuple(cov['order'])
        if not np.all(np.isfinite(C)):
            raise ValueError('its covariance is not finite')
        lam = np.linalg.eigvalsh(C[EXTRINSIC, EXTRINSIC])
        # a direction the batch stage held (one rotation axis) has no variance: semi-definite
        if lam[-1] <= 0.0 or lam[0] < -ROUNDING_RTOL * lam[-1]:
            raise ValueError('its covariance of T_HE is not positive semi-definite')
        e = doc['extrinsic']
        names = {'time_offset': doc['time_offset'], 'clock_drift': doc.get('clock_drift')}
        names['scale'] = doc.get('scale')
        values = {k: float(v) for k in order if (v := names.get(k)) is not None}
        cfg = doc.get('config') or {}
        need = _pair([cfg.get('precision_translation'), cfg.get('precision_rotation')])
        return cls(
            name,
            np.asarray(e['rotation'], dtype=float),
            np.asarray(e['translation'], dtype=float),
            C,
            order,
            values,
            need,
        )

    def to_dict(self) -> MemberDoc:
        """Plain data for a rig file; :meth:`from_dict` reads it back."""
        out: MemberDoc = {
            'translation': [float(v) for v in self.p_HE],
            'rotation': [float(v) for v in self.q_HE],
            'values': dict(self.values),
            'covariance': {
                'order': list(self.order),
                'matrix': [[float(v) for v in row] for row in self.covariance],
            },
        }
        if self.precision is not None:
            out['precision'] = list(self.precision)
        return out

    @classmethod
    def from_dict(cls, name: str, d: MemberDoc) -> Member:
        """Of :meth:`to_dict`'s data as a file holds it; ValueError when it is not that."""
        try:
            C = np.asarray(d['covariance']['matrix'], dtype=float)
            out = cls(
                name,
                np.asarray(d['rotation'], dtype=float).reshape(4),
                np.asarray(d['translation'], dtype=float).reshape(3),
                C,
                tuple(d['covariance']['order']),
                {str(k): float(v) for k, v in d['values'].items()},
                _pair(d.get('precision')),
            )
        except (KeyError, TypeError, ValueError) as err:
            raise ValueError(
                f'not a recording of a rig file ({type(err).__name__}: {err})'
            ) from None
        if C.shape != (len(out.order),) * 2 or 'time_offset' not in out.values:
            raise ValueError('not a recording of a rig file (its covariance does not fit)')
        return out


def _pair(v: object) -> tuple[float, float] | None:
    """Targets (translation [m], rotation [deg]) as a rig file or a result's options hold
    them, None when either is missing."""
    if not isinstance(v, list) or len(v) != 2 or any(x is None for x in v):
        return None
    return float(v[0]), float(v[1])


@dataclass(frozen=True)
class Joint:
    """The T_HE the members share: q_HE (x y z w), p_HE [m] and covariance 6x6 (translation,
    rotation; :func:`fuse`)."""

    q_HE: Floats
    p_HE: Floats
    covariance: Floats

    @property
    def std(self) -> Floats:
        return np.sqrt(np.diag(self.covariance))

    @property
    def held(self) -> Floats:
        """The directions (6, k) of T_HE no member determines (each turned about one axis
        only, the same one): the joint keeps the first member's value along them."""
        return undetermined(self.covariance)


def fuse(members: Sequence[Member]) -> Joint:
    """The T_HE that fits every member's reduced system best (module docstring), by
    Gauss-Newton on SE(3) from the most informative member."""
    if not members:
        raise ValueError('no recordings to fuse')
    # a member that held a direction (one rotation axis) informs nothing along it: its
    # information is the pseudo-inverse of its covariance, rank decided as the batch stage does
    info = [pseudo_inverse(m.extrinsic_covariance) for m in members]
    total = np.sum(info, axis=0)
    first = int(np.argmax([np.linalg.det(L) for L in info]))
    R, p = matrix_from_quat(members[first].q_HE), members[first].p_HE.astype(float)
    for _ in range(MAX_ROUNDS):
        q = quat_from_matrix(R)
        g = np.sum(
            [L @ difference(m.q_HE, m.p_HE, q, p) for m, L in zip(members, info, strict=True)],
            axis=0,
        )
        step = solve_determined(total, g)
        p, R = p + step[:3], R @ exp_so3(step[None, 3:])[0]
        if np.linalg.norm(step) < STEP_TOL:
            break
    cov = pseudo_inverse(total)
    return Joint(quat_from_matrix(R), p, 0.5 * (cov + cov.T))


def chi2_against(member: Member, others: Joint) -> tuple[float, int, Floats]:
    """Mahalanobis distance squared of a member's T_HE from a joint estimate that does not
    include it (their errors independent), its degrees of freedom and the difference (member
    [-] joint). A direction either holds (a lever arm along one rotation axis) is no test of
    agreement: the distance is taken on the directions both determine (6 when both do)."""
    d = difference(member.q_HE, member.p_HE, others.q_HE, others.p_HE)
    held = np.hstack([undetermined(member.extrinsic_covariance), undetermined(others.covariance)])
    P = np.eye(6)
    if held.shape[1]:
        u, s, _ = np.linalg.svd(held, full_matrices=False)
        span = u[:, s > RANK_SPAN * s[0]]
        P = P - span @ span.T
    S = P @ (member.extrinsic_covariance + others.covariance) @ P
    dp = P @ d
    dof = 6 - (0 if not held.shape[1] else span.shape[1])
    return float(dp @ solve_determined(S, dp)), dof, d


@dataclass(frozen=True)
class Conditioned:
    """A member's own parameters with T_HE fixed at the joint one: values and 1-sigma by name
    (time_offset [s], clock_drift [s/s], scale), as :attr:`Member.order` names them; and its
    whole covariance in that order once T_HE is the joint one (Cov(x) the joint's, Cov(y, x)
    = K Cov(x), Cov(y) the conditioned one; K as in :func:`conditioned`)."""

    values: dict[str, float]
    std: dict[str, float]
    covariance: Floats


def conditioned(member: Member, joint: Joint) -> Conditioned:
    """Back-substitution: the member's own parameters y given the joint x (Gaussian
    conditioning of its covariance on x, the Schur complement's second half):

        y | x = y_i + K (x [-] x_i),   K = C_yx C_xx^-1,
        Cov = C_yy - K C_xy + K Cov(x) K^T.
    """
    C = member.covariance
    own = [k for k in range(C.shape[0]) if not EXTRINSIC.start <= k < EXTRINSIC.stop]
    C_yx = C[own, EXTRINSIC]
    K = C_yx @ pseudo_inverse(member.extrinsic_covariance)
    shift = K @ difference(joint.q_HE, joint.p_HE, member.q_HE, member.p_HE)
    cov = np.zeros_like(C)
    cov[np.ix_(own, own)] = C[np.ix_(own, own)] - K @ C_yx.T + K @ joint.covariance @ K.T
    cov[own, EXTRINSIC] = K @ joint.covariance
    cov[EXTRINSIC, own] = cov[own, EXTRINSIC].T
    cov[EXTRINSIC, EXTRINSIC] = joint.covariance
    cov = 0.5 * (cov + cov.T)
    names = [member.order[k] for k in own]
    return Conditioned(
        {n: member.values[n] + float(s) for n, s in zip(names, shift, strict=True)},
        {n: float(np.sqrt(max(cov[k, k], 0.0))) for n, k in zip(names, own, strict=True)},
        cov,
    )
