"""The schema of a rig's file (``offline_calibrate --rig -o``, ``evaluate
--shared-extrinsic``'s rig.yaml, the node's ``rig_file``): the rig's T_HE with its covariance
and verdict, and every recording's own estimate, test and values at the rig's T_HE, as
typed dictionaries (:mod:`.document` holds a single recording's result document)."""

from __future__ import annotations

from typing import NotRequired, TypedDict

from .document import CovarianceDoc, QualityDoc, TransformDoc


class MemberDoc(TypedDict):
    """One recording's own estimate in a rig file: T_HE, its other values (dt, drift, scale)
    and the full covariance (:class:`~.rig.Member`)."""

    translation: list[float]
    rotation: list[float]
    values: dict[str, float]
    covariance: CovarianceDoc
    precision: NotRequired[list[float]]


class OwnDoc(MemberDoc):
    time_offset: float
    time_offset_std: float


class RigTestDoc(TypedDict):
    chi2: float
    translation_mm: float
    rotation_deg: float


class SharedDoc(TypedDict):
    """A recording's own parameters conditioned on the rig's T_HE, and their 1-sigmas."""

    values: dict[str, float]
    std: dict[str, float]


class RigRecordingDoc(TypedDict):
    name: str
    used: bool
    reason: str
    follows: NotRequired[bool]
    own: NotRequired[OwnDoc]
    test: NotRequired[RigTestDoc | None]
    shared: NotRequired[SharedDoc | None]


class RigExtrinsicDoc(TransformDoc):
    std: dict[str, list[float]]


class RigGroupDoc(TypedDict):
    recordings: list[str]
    extrinsic: RigExtrinsicDoc


class RigSectionDoc(TypedDict):
    quality: QualityDoc
    extrinsic: RigExtrinsicDoc | None
    covariance: CovarianceDoc | None
    used: list[str]
    followers: list[str]
    left_out: dict[str, str]
    groups: list[RigGroupDoc]
    chi2_threshold: float | None
    method: str
    units: dict[str, str]


class RigDoc(TypedDict):
    """A rig's file: the rig's T_HE and verdict, and its recordings."""

    rig: RigSectionDoc
    recordings: list[RigRecordingDoc]
