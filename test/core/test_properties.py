"""Properties of the paper's building blocks, on inputs hypothesis draws (issue 14).

Each test states an identity the paper's derivation relies on and checks it exactly (to
round-off) on generated cases, in the manner of scipy's test_rotation_spline: the true X lies
in the null space of the 6x8 blocks (eq. 4-5); the solver's unit constraints hold on any
system; the inlier criteria (eq. 13) equal a direct ``X B X^-1 A^-1``; the kernel (eq. 9-11)
is 1 for congruent screws; the parabola vertex (eq. 1's fit) is exact on a parabola; the
masked NCC equals a brute-force Pearson correlation; the keyframes (eq. 6) are the greedy chain.
Round-off tolerances are a few hundred ulps of the quantities compared.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from handeye_ros.core.geometry import (
    compose,
    dual_quat_from_pose,
    inverse,
    matrix_from_quat,
    pose_from_dual_quat,
    quat_from_matrix,
    rotation_angle,
)
from handeye_ros.core.linear.axxb import (
    Motions,
    constraint_gram,
    motion_errors,
    screw_log_weights,
    solve_gram,
)
from handeye_ros.core.linear.keyframes import rotation_keyframes
from handeye_ros.core.time.correlation import masked_normalised_correlation, parabola_vertex

SEEDS = st.integers(0, 2**32 - 1)
FAST = settings(max_examples=60, deadline=None)


def _pose(rng: np.random.Generator, n: int | None = None, min_angle_deg: float = 0.0):
    """Random rigid transforms (R, p): rotations of at least ``min_angle_deg``, metres-scale
    translations."""
    size = 1 if n is None else n
    axis = rng.normal(size=(size, 3))
    axis /= np.linalg.norm(axis, axis=1, keepdims=True)
    angle = np.deg2rad(rng.uniform(min_angle_deg, 170.0, size))
    R = Rotation.from_rotvec(axis * angle[:, None]).as_matrix()
    p = rng.normal(scale=0.5, size=(size, 3))
    return (R[0], p[0]) if n is None else (R, p)


def _motions(A, B) -> Motions:
    """Motions from relative poses, as build_motions makes them (w >= 0 on both sides)."""
    qa, qad = dual_quat_from_pose(quat_from_matrix(A[0]), A[1])
    qb, qbd = dual_quat_from_pose(quat_from_matrix(B[0]), B[1])
    n = A[0].shape[0]
    return Motions(np.arange(n), np.arange(n) + 1, A, B, qa, qad, qb, qbd, np.ones(n))


def _congruent(rng: np.random.Generator, n: int):
    """X and n motion pairs with ``A X = X B`` exactly (B = X^-1 A X)."""
    X = _pose(rng)
    A = _pose(rng, n, min_angle_deg=5.0)
    Xs = (np.broadcast_to(X[0], A[0].shape), np.broadcast_to(X[1], A[1].shape))
    B = compose(inverse(Xs), compose(A, Xs))
    return X, A, B


def _x_vector(X) -> np.ndarray:
    """X's dual quaternion in the column order of constraint_gram: (q_v, q_w, q'_v, q'_w)."""
    q, qd = dual_quat_from_pose(quat_from_matrix(X[0]), X[1])
    return np.concatenate((q, qd))


@FAST
@given(seed=SEEDS, n=st.integers(1, 8))
def test_true_extrinsic_is_in_the_null_space_of_every_block(seed: int, n: int) -> None:
    rng = np.random.default_rng(seed)
    X, A, B = _congruent(rng, n)
    G = constraint_gram(_motions(A, B))
    x = _x_vector(X)
    # x^T (S^T S) x = |S x|^2 = 0 for each motion's block (eq. 4), hence for M (eq. 5)
    residual = np.einsum('i,nij,j->n', x, G, x)
    scale = np.linalg.norm(G, axis=(1, 2))
    assert np.all(residual <= 1e-24 + 1e-13 * scale), residual / scale


@FAST
@given(seed=SEEDS, n=st.integers(2, 8))
def test_two_general_motions_determine_the_extrinsic(seed: int, n: int) -> None:
    rng = np.random.default_rng(seed)
    X, A, B = _congruent(rng, n)
    q, qd, sigma = solve_gram(constraint_gram(_motions(A, B)).sum(axis=0))
    # rank 6 (eq. 5): the two smallest singular values vanish, the sixth does not
    assert sigma[6] <= 1e-7 * sigma[0] and sigma[5] > 1e-4 * sigma[0], sigma
    q_X, p_X = pose_from_dual_quat(q, qd)
    np.testing.assert_allclose(matrix_from_quat(q_X), X[0], atol=1e-7)
    np.testing.assert_allclose(p_X, X[1], atol=1e-7)


@FAST
@given(seed=SEEDS, noise=st.floats(0.0, 1.0))
def test_solution_is_a_unit_dual_quaternion_whenever_one_exists(seed: int, noise: float) -> None:
    """|q| = 1 on any system. q . q' = 0 holds exactly whenever some combination of the two
    smallest singular vectors satisfies it (the quadratic in their weights has real roots,
    always so near a noise-free system); otherwise the solver returns the combination nearest
    to it, and pose_from_dual_quat projects q' onto q's orthogonal complement."""
    rng = np.random.default_rng(seed)
    _, A, B = _congruent(rng, 4)
    G = constraint_gram(_motions(A, B)).sum(axis=0)
    N = rng.normal(size=(8, 8))
    G = G + noise * (N @ N.T)
    q, qd, sigma = solve_gram(G)
    assert abs(np.linalg.norm(q) - 1.0) < 1e-12
    assert np.all(np.diff(sigma) <= 1e-12 * sigma[0])  # descending
    _, V = np.linalg.eigh(G)
    u1, u1d, u2, u2d = V[:4, 0], V[4:, 0], V[:4, 1], V[4:, 1]
    a, b, c = u1 @ u1d, u1 @ u2d + u2 @ u1d, u2 @ u2d
    if b * b - 4.0 * a * c >= 1e-12:
        assert abs(q @ qd) < 1e-10 * max(1.0, np.linalg.norm(qd))


@FAST
@given(seed=SEEDS, n=st.integers(1, 6), k=st.integers(1, 4))
def test_inlier_criteria_equal_a_direct_composition(seed: int, n: int, k: int) -> None:
    """e1, e2 of eq. 13 as the rotation angle and translation norm of X B X^-1 A^-1, for
    hypotheses X that are not the truth."""
    rng = np.random.default_rng(seed)
    A, B = _pose(rng, n, 1.0), _pose(rng, n, 1.0)
    hyp = _pose(rng, k)
    q_hyp = quat_from_matrix(hyp[0])
    e_rot, e_trans = motion_errors(_motions(A, B), q_hyp, hyp[1])
    for a in range(k):
        X = (np.broadcast_to(hyp[0][a], A[0].shape), np.broadcast_to(hyp[1][a], A[1].shape))
        E = compose(compose(X, compose(B, inverse(X))), inverse(A))
        np.testing.assert_allclose(e_rot[a], rotation_angle(E[0]), atol=2e-7)
        np.testing.assert_allclose(e_trans[a], np.linalg.norm(E[1], axis=1), atol=1e-12, rtol=1e-9)


@FAST
@given(seed=SEEDS, n=st.integers(1, 8), mu=st.floats(0.1, 100.0))
def test_kernel_is_one_for_congruent_screws_and_below_otherwise(
    seed: int, n: int, mu: float
) -> None:
    rng = np.random.default_rng(seed)
    _, A, B = _congruent(rng, n)
    # eq. 9: Scalar(A) = Scalar(B) for any X, so E = 1 and W = exp(0) = 1 (eq. 10-11)
    np.testing.assert_allclose(screw_log_weights(_motions(A, B), mu), 0.0, atol=1e-6 * mu)
    other = _pose(rng, n, 1.0)
    assert np.all(screw_log_weights(_motions(A, other), mu) <= 0.0)  # E >= 1: W <= 1


@FAST
@given(vertex=st.floats(-0.49, 0.49), curvature=st.floats(1e-3, 1e3), top=st.floats(-1.0, 1.0))
def test_parabola_vertex_is_exact_on_a_parabola(
    vertex: float, curvature: float, top: float
) -> None:
    c = [top - curvature * (x - vertex) ** 2 for x in (-1.0, 0.0, 1.0)]
    assert abs(parabola_vertex(*c) - vertex) < 1e-9


@FAST
@given(
    seed=SEEDS,
    ny=st.integers(3, 40),
    nx=st.integers(3, 40),
    channels=st.integers(1, 3),
    holes=st.floats(0.0, 0.4),
)
def test_masked_ncc_equals_a_brute_force_pearson(
    seed: int, ny: int, nx: int, channels: int, holes: float
) -> None:
    rng = np.random.default_rng(seed)
    y, x = rng.normal(size=(ny, channels)), rng.normal(size=(nx, channels))
    my, mx = rng.random(ny) >= holes, rng.random(nx) >= holes
    lags, ncc, overlap = masked_normalised_correlation(y, my, x, mx)
    # the FFT's sums are exact to some 1e-16 x log2(n) of the signals' energy; the Pearson value
    # divides that by the overlap's own spread (3000 seeds: at most 2.3e-14 of energy / spread;
    # an absolute 1e-8 failed near-degenerate overlaps on both numpy 1.26 and 2.4)
    energy = np.sqrt(np.sum(y * y) * np.sum(x * x))
    for lag, c, n in zip(lags, ncc, overlap, strict=True):
        k = np.arange(nx)
        k = k[(k + lag >= 0) & (k + lag < ny)]
        k = k[mx[k] & my[k + lag]]
        assert n == k.size
        if k.size < 2:
            continue
        a, b = y[k + lag] - y[k + lag].mean(axis=0), x[k] - x[k].mean(axis=0)
        var = np.sum(a * a) * np.sum(b * b)
        if var <= 1e-9:  # the FFT's round-off decides there: NaN or a value, never asserted
            continue
        assert abs(c - np.sum(a * b) / np.sqrt(var)) < 1e-12 * energy / np.sqrt(var)


@pytest.mark.slow
@FAST
@given(seed=SEEDS, n=st.integers(2, 120), eta_deg=st.floats(0.5, 30.0))
def test_keyframes_are_the_greedy_chain_of_eq_6(seed: int, n: int, eta_deg: float) -> None:
    rng = np.random.default_rng(seed)
    steps = Rotation.from_rotvec(rng.normal(scale=np.deg2rad(2.0), size=(n, 3)))
    R = np.stack([r.as_matrix() for r in _cumulative(steps)])
    i, j = rotation_keyframes(R, np.deg2rad(eta_deg))
    # brute force: from each keyframe, the first later frame at least eta away
    expect, k = [], 0
    while True:
        ang = np.degrees(rotation_angle(np.swapaxes(R[k], -1, -2) @ R[k + 1 :]))
        later = np.flatnonzero(ang >= eta_deg - 1e-9)
        if not later.size:
            break
        expect.append((k, k + 1 + int(later[0])))
        k = expect[-1][1]
    got = list(zip(i.tolist(), j.tolist(), strict=True))
    # frames within round-off of eta may go either way: compare away from the threshold
    ang_got = [np.degrees(rotation_angle(R[a].T @ R[b])) for a, b in got]
    assert all(a >= eta_deg - 1e-6 for a in ang_got)
    if all(
        abs(np.degrees(rotation_angle(R[a].T @ R[b])) - eta_deg) > 1e-6
        for a in range(n)
        for b in range(a + 1, n)
    ):
        assert got == expect


def _cumulative(steps: Rotation) -> list[Rotation]:
    out = [Rotation.identity()]
    for s in steps[1:]:
        out.append(out[-1] * s)
    return out
