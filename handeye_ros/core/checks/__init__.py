"""What real recordings need around the paper's three stages, and the verdict.

Not in the paper: :mod:`.screening` (damaged rows, placeholders, isolated outlier poses, on
:mod:`.running_median`),
:mod:`.breaks` (VIO resets found against the hand), :mod:`.conventions` (stamp units and epochs
the data contradict), :mod:`.orientations` (quaternion orders, inverted poses and mirrored
positions likewise), :mod:`.positions` (positions in other units, at a scale or not moving,
named when stage 2 fails),
:mod:`.selfcheck` (stage 2 at each candidate offset, scored alike) on :mod:`.excerpt` (a
bounded part of the recording), :mod:`.coverage` (how much of the eye's time the MoCap covers),
:mod:`.consistency` (which of a rig's recordings agree on T_HE), :mod:`.verdict` (good,
doubtful or failed, with its reasons), and :mod:`.readiness` (READY: the latest calibration of
the node's buffers is good; what the motion so far lacks, from :mod:`.excitation`: the turns
about each axis, the stream health).
"""
