"""Stage 1, time alignment (paper Section III-A): the offset dt between the two clocks.

:mod:`.signals` makes the signals eq. 1 correlates (each stream's angular speed on its own
uniform grid); :mod:`.align` is eq. 1: the angular-speed magnitudes of both streams on grids of
their own, their masked normalised cross-correlation over every lag and the quadratic fit around
the peak (:mod:`.correlation`); its vector form with stage 2's rotation
(``w_E(t) = R_EH w_H(t - dt)``) measures the offset in windows along the recording.
:mod:`.keyframe_only` aligns a keyframe-only eye from the rotation angles of its keyframe pairs
(the screw congruence of eq. 9), where no angular speed can be resampled, and
:mod:`.keyframe_errors` says why when it cannot. :mod:`.clock` is
beyond the paper: the offset measured in windows along the recording, and a linear clock
(drift) fitted to it.
"""
