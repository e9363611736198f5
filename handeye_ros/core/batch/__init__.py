"""Stage 3, batch estimation (paper Section III-C, eq. 14-16), split as Ceres splits a problem.

:mod:`.spline` is the hand's cumulative B-spline on SO(3) and R^3 (eq. 14), one per gap-free
part of the MoCap; :mod:`.residuals` the cost functions: the relative eye residuals of eq. 16
and their Jacobians (with the model
``T_WE(t) = T_WG T_GH(t - dt) T_HE`` stated with eq. 15);
:mod:`.loss` the Huber loss of eq. 15; :mod:`.levenberg_marquardt` Levenberg-Marquardt, with
:mod:`.rank` deciding which directions its normal matrices determine;
:mod:`.covariance` and :mod:`.long_run` the uncertainty of (dt, T_HE), the latter for residuals
correlated in time, and :mod:`.correlated` what a real VIO adds to it (errors correlated over
minutes, its scale); :mod:`.refine` the problem: what is solved and the answer it gives;
:mod:`.solves` the solve in its steps and passes, as
:mod:`.options` says;
:mod:`.noise` each stream's noise from its residuals; :mod:`.parameters` its parameters and how the solvers walk the residuals; :mod:`.pieces`
the hand's gap-free parts, one spline each; :mod:`.spacing` the spline's spacing where the
MoCap is noisy for its eye, and how far its noise moves the answer. The stage as the pipeline runs it is
:mod:`handeye_ros.core.stages.batch`.
"""
