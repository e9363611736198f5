"""Monocular scale: an eye whose positions are metric only after a factor s.

A monocular VO (and a VIO before its scale converges) gives ``T_WE`` with positions s times too
small: ``s p_WE`` is metric. In AX = XB (eq. 2-3) s multiplies the eye's relative translations
only, so that, with the rotation R_X found from the rotations alone (scale-free), the
translation part ``(R_A - I) t_X = R_X (s t_B) - t_A`` is linear in (t_X, s), as in the
hand-eye-with-structure-from-motion literature (Andreff et al. 2001). In the dual-quaternion
form (eq. 4) s multiplies the eye's dual part: with the rotation q fixed, the lower rows are
linear in (q', s) (Schmidt et al. 2005) -- the paper's baseline with scale.

The pipeline uses these three ways: :func:`scale_prior` (before stage 2, so that its
thresholds in metres mean metres), the refits of stage 2 (:func:`translation_and_scale`,
:func:`dual_quaternion_scale`), and :func:`scale_check`, which compares the translation fit
with and without s when no scale is estimated, to name an eye that needs one.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.linalg import null_space

from ..arrays import Floats
from ..geometry import matrix_from_quat, pose_from_dual_quat, skew

#: The scale is not observable when its relative standard deviation exceeds this: the hand
#: barely translates, and t_X and s trade against each other.
MAX_SCALE_STD_FRACTION = 0.05
#: A default run is doubtful for a scale that differs from 1 by more than this fraction, by more
#: than SCALE_SIGMAS of its own uncertainty, and lowers the translation residuals by
#: SCALE_RESIDUAL_DROP or more (a monocular VO: a metric VIO is off by a few per cent at most),
#: and for a smaller one that moves T_HE beyond the required precision (:meth:`ScaleFit.costs`).
SCALE_NOTICE = 0.05
SCALE_SIGMAS = 3.0
SCALE_RESIDUAL_DROP = 0.2
#: A scale this far from 1 (beyond SCALE_SIGMAS, explaining the translations) is named in the
#: notes whatever it costs: a metric VIO off by a few per cent is worth knowing of before any
#: metric is computed (:attr:`ScaleFit.clear`).
SCALE_MENTION = 0.01
#: Robust loss of the scale fits: Huber at this many robust sigmas of a plain fit's residuals.
HUBER_SIGMAS = 2.0


@dataclass(frozen=True)
class ScaleFit:
    """``s`` with ``s * eye positions`` metric, its standard deviation, the translation of T_HE
    fitted with it (m), and the median translation residual with and without s (in the eye's
    units; the latter with s fixed to 1 and t_X refitted); ``p_HE_unscaled``: the translation
    of T_HE fitted with s fixed to 1 (m)."""

    scale: float
    scale_std: float
    p_HE: Floats
    rms_with: float
    rms_without: float
    p_HE_unscaled: Floats | None = None

    @property
    def clear(self) -> bool:
        """Whether the eye is scaled: s differs from 1 beyond SCALE_MENTION and SCALE_SIGMAS of
        its uncertainty, and explains the translations (lowers their residuals by
        SCALE_RESIDUAL_DROP; a drifting VIO's errors also fit a scale a little, but a scale
        does not explain them: on the 12 published EuRoC estimates the drop is at most 5 %)."""
        d = abs(self.scale - 1.0)
        return (
            self.observable
            and d > SCALE_SIGMAS * self.scale_std
            and d > SCALE_MENTION
            and self.rms_with < (1.0 - SCALE_RESIDUAL_DROP) * self.rms_without
        )

    @property
    def shift_m(self) -> float:
        """How far taking s = 1 moves T_HE's translation (m)."""
        if self.p_HE_unscaled is None:
            return 0.0
        return float(np.linalg.norm(self.p_HE - self.p_HE_unscaled))

    @property
    def observable(self) -> bool:
        return observable(self.scale, self.scale_std)

    @property
    def significant(self) -> bool:
        """Whether the eye is clearly scaled by more than SCALE_NOTICE (a monocular VO)."""
        return self.clear and abs(self.scale - 1.0) > SCALE_NOTICE


def _system(
    R_A: Floats, t_A: Floats, t_B: Floats, R_X: Floats, w: Floats
) -> tuple[Floats, Floats]:
    """Rows of ``(R_A - I) v + u t_A = R_X t_B`` over (v, u) = (t_X / s, 1 / s), three per
    motion, weighted: eq. 2's translation part divided by s, so that the noisy eye is on the
    right and the exact MoCap on the left (with s on the left, a motion's eye noise would sit in
    a regressor), and so that a hand that does not translate shows as a zero column for u
    rather than as the exact but meaningless solution s = 0, t_X = 0."""
    lhs = np.concatenate((R_A - np.eye(3), t_A[:, :, None]), axis=2)
    return (lhs * w[:, None, None]).reshape(-1, 4), ((t_B @ R_X.T) * w[:, None]).reshape(-1)


def translation_and_scale(
    R_A: Floats,
    t_A: Floats,
    t_B: Floats,
    R_X: Floats,
    w: Floats | None = None,
    robust: bool = False,
) -> ScaleFit:
    """(t_X, s) by least squares from motions (n,) given R_X, each motion's rows weighted by w
    (see :func:`_system` for the form solved).

    ``robust``: a Huber loss (scipy's least_squares) instead of plain least squares, for
    motions that may hold outliers. The standard deviation of s follows from that of u = 1/s,
    ``s2 / |u's column with the others projected out|^2`` (infinite when the hand does not
    translate); the residuals are not white for a drifting eye, so it is a first figure (the
    batch stage's is the one to trust).
    """
    w = np.ones(R_A.shape[0]) if w is None else w
    lhs, rhs = _system(R_A, t_A, t_B, R_X, w)
    z = np.linalg.lstsq(lhs, rhs, rcond=None)[0]
    if robust:
        r0 = lhs @ z - rhs
        f_scale = max(HUBER_SIGMAS * 1.4826 * float(np.median(np.abs(r0))), 1e-12)
        from scipy.optimize import least_squares  # here: its import is 0.5 s of every run

        z = least_squares(
            lambda v: lhs @ v - rhs, z, loss='huber', f_scale=f_scale, jac=lambda v: lhs
        ).x
    r = lhs @ z - rhs
    s2 = float(r @ r) / max(rhs.size - 4, 1)
    V, c = lhs[:, :3], lhs[:, 3]
    c_perp = c - V @ np.linalg.lstsq(V, c, rcond=None)[0]
    info = float(c_perp @ c_perp)
    u = float(z[3])
    u_std = np.sqrt(s2 / info) if info > 1e-12 * max(float(c @ c), 1e-300) else np.inf
    scale = 1.0 / u if u != 0.0 else np.inf
    scale_std = u_std / (u * u) if u != 0.0 else np.inf
    # the fit without a scale (u = 1), on the same rows (and with the same loss)
    v1 = np.linalg.lstsq(V, rhs - c, rcond=None)[0]
    if robust:
        v1 = least_squares(
            lambda v: V @ v - (rhs - c), v1, loss='huber', f_scale=f_scale, jac=lambda v: V
        ).x
    r1 = V @ v1 - (rhs - c)
    with np.errstate(invalid='ignore', over='ignore'):
        p_HE = z[:3] * scale if np.isfinite(scale) else np.full(3, np.nan)
    return ScaleFit(float(scale), float(scale_std), p_HE, _rms(r, w), _rms(r1, w), v1)


def observable(scale: float, std: float) -> bool:
    """Whether a scale estimate says anything: positive, finite, and with a relative standard
    deviation within MAX_SCALE_STD_FRACTION."""
    return bool(
        np.isfinite(scale)
        and scale > 0.0
        and np.isfinite(std)
        and std <= MAX_SCALE_STD_FRACTION * scale
    )


def _rms(r: Floats, w: Floats) -> float:
    """RMS of the unweighted residual norms per motion (m), robustly: the median norm."""
    norms = np.linalg.norm(r.reshape(-1, 3), axis=1) / np.maximum(w, 1e-12)
    return float(np.median(norms))


def dual_quaternion_scale(
    qa: Floats, qad: Floats, qb: Floats, qbd: Floats, q: Floats, w: Floats
) -> tuple[Floats, float]:
    """The dual part q' and the scale s of eq. 4 with the rotation q (x y z w) fixed.

    The eye's dual part scales with its translation, so the lower rows of each 6x8 block read
    ``[r' + s s']^ q_v + (r' - s s') q_w + (r + s)^ q'_v + (r - s) q'_w = 0`` (r, r': hand vector
    parts; s, s' the eye's, s' before scaling): linear in (q', s). ``q . q' = 0`` holds by
    writing q' in the orthogonal complement of q. Returns (p_HE in metres, s).
    """
    r, rd, e, ed = qa[:, :3], qad[:, :3], qb[:, :3], qbd[:, :3]
    qv, qw = q[:3], q[3]
    n = r.shape[0]
    N = null_space(q[None, :])  # (4, 3): q' = N z
    A_dual = np.concatenate((skew(r + e), (r - e)[:, :, None]), axis=2) @ N  # (n, 3, 3)
    a_s = np.einsum('nij,j->ni', skew(ed), qv) - ed * qw
    lhs = np.concatenate((A_dual, a_s[:, :, None]), axis=2) * w[:, None, None]
    rhs = -(np.einsum('nij,j->ni', skew(rd), qv) + rd * qw) * w[:, None]
    z = np.linalg.lstsq(lhs.reshape(n * 3, 4), rhs.reshape(-1), rcond=None)[0]
    _, p = pose_from_dual_quat(q, N @ z[:3])
    return p, float(z[3])


def scale_prior(R_A: Floats, t_A: Floats, t_B: Floats, q_HE: Floats, w: Floats) -> ScaleFit:
    """A first scale for an eye of unknown scale, from motions and a rotation of T_HE found
    from rotations alone (robust: a scale is needed before stage 2's thresholds in metres
    mean anything)."""
    return translation_and_scale(R_A, t_A, t_B, matrix_from_quat(q_HE), w, robust=True)
