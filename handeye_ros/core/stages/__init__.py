"""The stages as the pipeline runs them: the wiring above the paper's math.

Each module takes a stage's math (:mod:`..time`, :mod:`..linear`, :mod:`..batch`) and what real
recordings need around it (:mod:`..checks`), in :func:`..pipeline.calibrate`'s order:

- :mod:`.prepare`: the inputs (stamp units, epochs, keyframe-only eyes, screening);
- :mod:`.time`: stage 1 and the orientation conventions at its offset;
- :mod:`.drift`: the offset along the recording (drift) around stage 2;
- :mod:`.scale`: the eye's scale around stage 2;
- :mod:`.linear`: stage 2 with the eye's breaks, the self-check over the candidate offsets and
  the seed check;
- :mod:`.batch`: stage 3 from stage 2's answer, checked against it, with its uncertainty.

Each returns a frozen record of what it computed, with what it found on the way (its warnings,
notes and facts: :class:`..checks.verdict.Findings`), which only the verdict reads into reasons.
The math below never imports these, nor the checks; only these call the checks.
"""
