"""Stage 2, robust linear calibration (paper Section III-B, eq. 2-13 and Algorithm 1).

:mod:`.keyframes` chooses the relative motions (rotation-constrained keyframes, eq. 6, or the
baselines); :mod:`.axxb` holds the dual-quaternion algebra: the motions A and B (eq. 2-3), the
6x8 blocks (eq. 4), the null space with the unit constraints (eq. 5), the screw-congruence
kernel (eq. 7-11) and the inlier criteria (eq. 13); :mod:`.ransac` is Algorithm 1's loop
(RANSAC on two-motion subsets, the robust solve of eq. 12, the smallest sigma7/sigma6) with
adaptive inliers, and :mod:`.robust` runs it and refits on its consensus; :mod:`.refits` re-estimates rotation and translation apart on the final consensus;
:mod:`.scale` adds a monocular scale to the translation part.
"""
