"""The verdict: how far a calibration can be trusted, and why.

Every calibration ends with ``quality.verdict``, judged for its ``purpose``
(:class:`Purpose`: ``evaluation``, the default, or ``extrinsic``; each reason names the
purposes whose verdict it lowers, and ``quality.other`` is the other purpose's verdict):

- ``good``: every check passed; the numbers and their sigmas can be used as they are;
- ``doubtful``: a number is given, but something the user must look at is wrong or unknown
  (each ``reason`` says what); an evaluation built on it needs that looked at first;
- ``failed``: the data contradict the result (the calibrated MoCap does not explain the VIO);
  the numbers are given only to help find out why.

The reasons (``code``: what, and when; :class:`Code` names them, :data:`SEVERITY` gives each
its verdict, and the thresholds below are the rules' numbers):

==========================  =========  =================================================
code                        severity   when
==========================  =========  =================================================
convention_corrected        doubtful   a stamp unit, quaternion order or pose inversion was
                                       assumed (the file still holds the mistake)
outliers_removed            doubtful   screening removed more than OUTLIER_FRACTION_DOUBTFUL
                                       of a stream
ambiguous_offset            doubtful   two offsets explain the data almost equally (the
                                       self-check's runner-up scores within
                                       AMBIGUOUS_SCORE_RATIO of the winner), or the
                                       correlation has a second peak above 0.9 that no
                                       self-check ran on
offset_disagrees            doubtful   the time offset the user fixed disagrees with the
                                       angular-speed correlation (by more than
                                       FIXED_OFFSET_DISAGREEMENT_S)
weak_correlation            doubtful   the angular velocities hardly agree (correlation
                                       below 0.5)
stages_disagree             doubtful   the batch stage moved the offset or the extrinsic
                                       beyond its sigmas (BATCH_*) and the self-check sided
                                       against it
few_inliers                 doubtful   fewer than 20 % of the motions are RANSAC inliers
weak_excitation             doubtful   the rotation axes spread less than 10 deg
unobservable                doubtful   a component of T_HE, the clock drift or the scale
                                       cannot be determined (named); for purpose
                                       evaluation not the lever arm along a ground robot's
                                       only rotation axis, held (no figure depends on it)
seed_dependent              doubtful   the linear stage's answer moves with the RANSAC seed
                                       (beyond SEED_*)
no_uncertainty              doubtful   the batch stage could not run or was switched off:
                                       no sigmas, so no precision is judged
imprecise                   doubtful   purpose evaluation: the calibration's 1-sigma on an
                                       APE/RPE figure exceeds EVALUATION_SHARE of it (named
                                       with the parameters that move it most, THROUGH);
                                       purpose extrinsic: a 1-sigma of dt or T_HE exceeds
                                       the required precision (options
                                       precision_time_offset, _translation, _rotation;
                                       default 1 ms, 1 cm, 0.5 deg)
clock_drift                 doubtful   without clock_drift: the offset measured in windows
                                       changes along the recording by more than
                                       DRIFT_NOTICE_S and DRIFT_SIGMAS (the rate is named)
scale                       doubtful   without estimate_scale: a scale explains the eye's
                                       translations and is large (a monocular VO, other
                                       units; named with its value); a metric VIO a few per
                                       cent off is a note (T_HE is fitted with it free)
residuals_not_white         doubtful   the long-run covariance is more than
                                       INFLATION_DOUBTFUL times the white one (an
                                       unmodelled effect: clock drift, scale, ...)
noisy_mocap                 doubtful   the MoCap's noise drawn once more moves dt or T_HE
                                       by more than NOISE_MOVE_DOUBTFUL sigmas: the spline
                                       held through it as exact has biased them as far
inconsistent                failed     AX = XB does not hold: over the keyframe motions
                                       (eq. 6), the median rotation error exceeds
                                       FAILED_MOTION_ROTATION_DEG, or the median translation
                                       error exceeds FAILED_MOTION_TRANSLATION_M and
                                       FAILED_MOTION_TRANSLATION_FRACTION of the median
                                       motion (relative motions: the VIO's drift does not
                                       enter, unlike APE)
==========================  =========  =================================================

The words (:class:`Verdict`, :class:`Code`, :data:`SEVERITY`, the thresholds, :class:`Reason`,
:class:`Quality`) are in :mod:`.codes`. Facts in, verdict out: a stage records what it measured
or met as a fact (:mod:`.facts`: a scale or a drift measured, a rerun with the next seed, the
batch stage's move the self-check did not support, a reading corrected, a drift it could not
observe) and never makes a reason; :mod:`.during` says what each fact means (:func:`read`) and
holds the decisions a stage needs to go on (the batch stage's move, the self-check's tie, a
scale that keeps the eye whole); :mod:`.final` holds the rules judged on the finished run
(:func:`assess_streams`, :func:`assess_answer`, :func:`assess_model`) and the verdict they
end in (:func:`judged`). Each step returns what it found as a frozen :class:`Findings`
(:mod:`.findings`: its warnings, notes, facts and reasons in order), and the verdict reads
their sum once.

A rig of many recordings (:mod:`..rig_pipeline`) has its own verdict, judged for the purpose
of its recordings (extrinsic when any asks for it), from its own rules (:mod:`.rig`:
:func:`assess_rig`, and :func:`judge_rig_figures` once the recordings are evaluated at the
rig's T_HE; the groups are :mod:`..consistency`'s):

==========================  =========  =================================================
recording_left_out          doubtful   a recording gave no calibration, or its T_HE
                                       disagrees with the others' (named with the
                                       difference); the rig's T_HE is computed without it
groups                      doubtful   the recordings form groups that agree within
                                       themselves and not with each other (a moved
                                       marker); the rig's T_HE is the largest group's,
                                       each group is reported
no_agreement                failed     fewer than two recordings agree, or the largest
                                       groups are as large as each other (a rig of one
                                       recording and nothing else is not said)
unobservable                doubtful   purpose extrinsic: a direction of the rig's T_HE
                                       that no recording determines (each turned about
                                       the same one axis: the lever arm along it)
imprecise                   doubtful   purpose evaluation: at the rig's T_HE, the
                                       calibration's 1-sigma on a figure of a recording
                                       that takes it exceeds EVALUATION_SHARE of it (the
                                       recording named); purpose extrinsic: the rig's
                                       1-sigma of T_HE exceeds the precision its
                                       recordings required (the strictest of theirs)
==========================  =========  =================================================

Notes that do not lower the verdict (resets split, an epoch difference, a self-check that
settled clearly) are in ``notes``.
"""

from __future__ import annotations

from .codes import (
    AMBIGUOUS_PEAK_RATIO,
    BLOCKS_MARGIN,
    EVALUATION_SHARE,
    SEVERITY,
    WEAK_CORRELATION,
    Code,
    Purpose,
    Quality,
    Reason,
    Verdict,
)
from .during import (
    batch_moved,
    batch_supported,
    convention_corrected,
    drift_explains,
    drift_explains_note,
    drift_fitted_note,
    drift_significant,
    drift_threshold_sigmas,
    judge_tie,
    read,
    scale_keeps_whole,
    scale_uncertainty_note,
    seed_reason,
    stages_disagree,
    varies_note,
)
from .facts import (
    DriftMeasured,
    DriftUnobservable,
    FixedOffsetDisagrees,
    ScaleMeasured,
    SeedCompared,
    SeedFailed,
    StagesDisagree,
)
from .final import (
    assess_answer,
    assess_evaluation,
    assess_model,
    assess_streams,
    judged,
    judged_ratio,
    motion_inconsistency,
    precision_ratio,
    precision_ratios,
    settled,
    sigmas_of,
)
from .findings import Findings
from .rig import assess_rig, judge_rig_figures

__all__ = [
    'AMBIGUOUS_PEAK_RATIO',
    'BLOCKS_MARGIN',
    'EVALUATION_SHARE',
    'SEVERITY',
    'WEAK_CORRELATION',
    'Code',
    'DriftMeasured',
    'DriftUnobservable',
    'Findings',
    'FixedOffsetDisagrees',
    'Purpose',
    'Quality',
    'Reason',
    'ScaleMeasured',
    'SeedCompared',
    'SeedFailed',
    'StagesDisagree',
    'Verdict',
    'assess_answer',
    'assess_evaluation',
    'assess_model',
    'assess_rig',
    'assess_streams',
    'batch_moved',
    'batch_supported',
    'convention_corrected',
    'drift_explains',
    'drift_explains_note',
    'drift_fitted_note',
    'drift_significant',
    'drift_threshold_sigmas',
    'judge_rig_figures',
    'judge_tie',
    'judged',
    'judged_ratio',
    'motion_inconsistency',
    'precision_ratio',
    'precision_ratios',
    'read',
    'scale_keeps_whole',
    'scale_uncertainty_note',
    'seed_reason',
    'settled',
    'sigmas_of',
    'stages_disagree',
    'varies_note',
]
