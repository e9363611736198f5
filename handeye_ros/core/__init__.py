"""The algorithm: numpy and scipy only, never rclpy (test_layout checks it).

Notation
--------
``T_A_B`` (also ``T_AB``) is the pose of frame B in frame A and reads right to left:
``p_A = T_AB p_B``, and ``T_AC = T_AB T_BC``. Frames: G the MoCap world, H the MoCap marker
(the *hand*), W the VIO world, E the VIO body (the *eye*). Both streams obey

    T_WE(t) = T_WG T_GH(t - dt) T_HE

so ``dt`` is the eye clock minus the hand clock for the same instant, ``T_HE`` the eye in the
hand frame (the extrinsic) and ``T_WG`` the world alignment. Rotations are (..., 3, 3) arrays
or Hamilton quaternions stored ``x y z w``; a pose is a tuple ``(R, p)`` of arrays, stacked
along the first axis (array-first, as scipy.spatial.transform). Stamps are int64 nanoseconds;
float seconds only after subtracting a common origin.

The layout follows the method. The stages, in :func:`.pipeline.calibrate`'s order: :mod:`.time`
(stage 1, eq. 1, and eq. 9 for keyframe-only eyes), :mod:`.linear` (stage 2, eq. 2-13 and
Algorithm 1), :mod:`.batch` (stage 3, eq. 14-16): the paper's math, which never imports what
is above it; :mod:`.checks` holds what real recordings need around them and the verdict; and
:mod:`.stages` wires each stage with its checks as the pipeline runs it (test_layout keeps that
order). Beside them the foundations: the array types of every signature (:mod:`.arrays`),
poses and streams (:mod:`.geometry`, :mod:`.trajectory`, :mod:`.association`), the options
(:mod:`.options`, :mod:`.config`), the result (:mod:`.result`, its plain-data sections
:mod:`.result_sections` and their schema :mod:`.document`, :mod:`.world`, :mod:`.eye_model`)
and the errors.
Beyond one recording: :mod:`.rig` (the T_HE many recordings of one rig share, its file's schema
:mod:`.rig_document`) and
:mod:`.rig_pipeline` (the rig's recipe, and a recording's result at the rig's T_HE). Tools: :mod:`.chunked`
(element-wise work on long streams, a chunk of rows at a time) and :mod:`.simulate` (recordings
with a known truth, the paper's protocol).
docs/method.md maps every equation to its function and lists the departures from the paper.
"""
