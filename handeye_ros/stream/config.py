"""Options of the two pose streams: topics, message types, frames and buffer bounds.

Shared by the node (parameters) and the bag replay of the offline tool (``--config``, and
``--hand-topic`` / ``--eye-topic``), so that a bag replays exactly as the node would buffer it.
"""

from __future__ import annotations

from dataclasses import dataclass

from ..core.errors import ConfigError
from ..core.options import Options, option
from .convert import MULTI_POSE_TYPES, SUPPORTED_TYPES, UnsupportedTypeError, normalise_type
from .sources import parse_selector

_TYPES = ', '.join(dict.fromkeys(t.rsplit('/', 1)[1] for t in SUPPORTED_TYPES + MULTI_POSE_TYPES))
_SELECTORS = (
    '; TOPIC:PARENT.CHILD selects a frame of tf2_msgs/TFMessage (e.g. '
    '/tf:world.marker, static transforms from /tf_static chained), TOPIC:NAME a rigid '
    'body of mocap4r2_msgs/RigidBodies'
)

#: Frame names where neither the options nor the messages give one.
FALLBACK_FRAMES = {
    'hand': 'mocap_marker',
    'eye': 'imu',
    'hand_world': 'mocap',
    'eye_world': 'odom',
}


@dataclass(frozen=True)
class StreamConfig(Options):
    """Where the hand and eye poses come from and how many are kept."""

    hand_topic: str = option(
        '/mocap/pose',
        'str',
        'topic of the MoCap pose of the marker frame H in the MoCap world G' + _SELECTORS,
    )
    eye_topic: str = option(
        '/vio/odom',
        'str',
        'topic of the VO/VIO pose of the body frame E in the VIO world W'
        ' (a selector, as hand_topic)',
    )
    hand_type: str = option(
        'auto',
        'str',
        f'message type of hand_topic: auto (from the graph or the bag) or {_TYPES}',
        expert=True,
    )
    eye_type: str = option(
        'auto',
        'str',
        f'message type of eye_topic: auto (from the graph or the bag) or {_TYPES}',
        expert=True,
    )
    hand_frame_id: str = option(
        '',
        'str',
        'frame id of H, parent of the published extrinsic T_HE; empty: the frame the '
        "hand messages name (child_frame_id, the /tf pair's child, the rigid body's name), or "
        f'{FALLBACK_FRAMES["hand"]!r} when they name none (PoseStamped, files)',
    )
    eye_frame_id: str = option(
        '',
        'str',
        'frame id of E, child of the published extrinsic T_HE; empty: the frame the '
        f'eye messages name, or {FALLBACK_FRAMES["eye"]!r}',
    )
    hand_world_frame_id: str = option(
        '',
        'str',
        "frame id of the MoCap world G; empty: the hand messages' header frame_id, "
        f'or {FALLBACK_FRAMES["hand_world"]!r}',
        expert=True,
    )
    eye_world_frame_id: str = option(
        '',
        'str',
        "frame id of the VIO world W; empty: the eye messages' header frame_id, or "
        f'{FALLBACK_FRAMES["eye_world"]!r}',
        expert=True,
    )
    use_arrival_time: str = option(
        'none',
        'str',
        "stamp a stream's poses with their arrival time (the node's clock, or "
        "the bag's record time) instead of header.stamp, for publishers that leave the stamp "
        'unset (zero) or frozen; less accurate: the transport delay becomes part of the time '
        'offset and its jitter noise, and the result says so',
        choices=('none', 'hand', 'eye', 'both'),
        expert=True,
    )
    buffer_size: int = option(
        500_000,
        'int',
        'most poses buffered per stream (preallocated, 64 bytes each); the '
        'oldest are dropped first',
        low=100,
        high=50_000_000,
        expert=True,
    )
    buffer_duration: float = option(
        1800.0,
        'float',
        'longest time span buffered per stream [s]; older poses are dropped',
        low=1.0,
        high=86_400.0,
        expert=True,
    )

    def frames(self, seen: dict[str, str] | None = None) -> dict[str, str]:
        """The four frame names (keys of FALLBACK_FRAMES): the option where set, else what the
        messages named (``seen``, same keys), else the fallback."""
        seen = seen or {}
        return {
            k: getattr(self, f'{k}_frame_id') or seen.get(k) or fallback
            for k, fallback in FALLBACK_FRAMES.items()
        }

    def validate(self) -> None:
        super().validate()
        for name in ('hand_type', 'eye_type'):
            value = getattr(self, name)
            if value != 'auto':
                try:
                    normalise_type(value)
                except UnsupportedTypeError as err:
                    raise ConfigError(f'option {name}: {err}') from None
        selectors = []
        for name in ('hand_topic', 'eye_topic'):
            if not getattr(self, name).strip():
                raise ConfigError(f'option {name} must not be empty')
            try:
                selectors.append(parse_selector(getattr(self, name)))
            except ConfigError as err:
                raise ConfigError(f'option {name}: {err}') from None
        hand, eye = selectors
        # one topic carries both streams only as two items of a many-pose message (a selector
        # without its item is said against what the topic holds, where its type is known)
        if hand.topic == eye.topic and (hand.item == eye.item):
            raise ConfigError(
                f'options hand_topic and eye_topic both read {hand.text}: the hand is the '
                "MoCap's topic and the eye the device's (one topic carries both only as two "
                'frame pairs of tf, TOPIC:PARENT.CHILD, or two bodies of RigidBodies, TOPIC:BODY)'
            )
