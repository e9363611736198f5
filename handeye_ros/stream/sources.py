"""Where a stream's poses come from when one message holds many: /tf and mocap4r2 rigid bodies.

A stream is named by a topic *selector* (evo's syntax for tf, extended to rigid bodies):

- ``/mocap/pose``: a topic of single poses (PoseStamped, Odometry, ...; see convert.py);
- ``/tf:PARENT.CHILD`` (optionally ``:/tf_static``, the static topic): the pose of CHILD in
  PARENT from tf2_msgs/TFMessage, through any chain of static transforms and exactly one
  moving transform of the tf tree (the one whose stamps the poses take);
- ``/rigid_bodies:NAME``: the rigid body NAME of mocap4r2_msgs/RigidBodies, stamped by the
  message header (the capture time).

Everything here reads message attributes only, so it serves rclpy messages (the node) and
rosbags messages (bag replay) alike.

tf: the moving transform's samples are buffered as published; the static parts on either
side (and an inversion, when the chain climbs the moving link) are applied to the whole
stream at once when the buffer is copied out (:meth:`TfChain.finish`), which keeps the
per-message cost to one dictionary look-up at 1 kHz and the result exact to rounding.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from ..core.arrays import Floats
from ..core.errors import ConfigError
from ..core.trajectory import Trajectory
from .convert import StampedPose, frame_name, stamped_pose
from .shapes import Header, RigidBodies, TFMessage

#: The static topic of a tf selector that names none.
TF_STATIC = '/tf_static'
#: How many names (frames, bodies) a diagnosis lists at most.
LISTED = 12


@dataclass(frozen=True)
class Selector:
    """A stream's topic selector: the topic, and for many-pose messages which pose.

    item: None (one pose per message), 'PARENT.CHILD' (tf) or a rigid body name.
    static_topic: the topic of the static transforms (tf selectors only)."""

    text: str
    topic: str
    item: str | None = None
    static_topic: str | None = None

    @property
    def topics(self) -> tuple[str, ...]:
        """Every topic the stream reads: the topic, then the static topic if any."""
        return (self.topic,) + ((self.static_topic,) if self.static_topic else ())

    def frames(self) -> tuple[str, str]:
        """(parent, child) of a tf selector; raises ConfigError when the item names no pair."""
        parent, _, child = (self.item or '').partition('.')
        parent, child = frame_name(parent), frame_name(child)
        if not parent or not child:
            raise ConfigError(
                f'{self.text}: a tf selector names two frames, as '
                f'{self.topic}:PARENT.CHILD (e.g. /tf:world.base_link)'
            )
        if parent == child:
            raise ConfigError(f'{self.text}: parent and child are the same frame {parent!r}')
        return parent, child


def parse_selector(text: str) -> Selector:
    """``TOPIC``, ``TOPIC:ITEM`` or ``TOPIC:PARENT.CHILD:STATIC_TOPIC`` (raises ConfigError).

    A third part is only meaningful for tf; whether ITEM is a frame pair or a body name is
    decided by the topic's message type (see :func:`source_for`)."""
    text = text.strip()
    topic, sep, rest = text.partition(':')
    if not topic or (sep and not rest):
        raise ConfigError(
            f'topic selector {text!r}: expected TOPIC, TOPIC:ITEM or '
            'TOPIC:PARENT.CHILD[:STATIC_TOPIC]'
        )
    if not sep:
        return Selector(text, topic)
    item, sep2, static = rest.partition(':')
    if sep2 and not static.startswith('/'):
        raise ConfigError(
            f'topic selector {text!r}: the static topic after the second colon '
            'must be a topic name starting with /'
        )
    return Selector(text, topic, item, static or None)


def _stamp(header: Header) -> int:
    return int(header.stamp.sec) * 1_000_000_000 + int(header.stamp.nanosec)


class RigidBodyPicker:
    """The pose of one named body out of mocap4r2_msgs/RigidBodies messages."""

    def __init__(self, name: str):
        self.name = name
        self.seen: dict[str, int] = {}

    def pose(self, msg: RigidBodies) -> StampedPose | None:
        """The body's stamped pose, or None when this message lacks it (not tracked)."""
        for body in msg.rigidbodies:
            if body.rigid_body_name == self.name:
                pose = body.pose
                return stamped_pose(_stamp(msg.header), pose.position, pose.orientation)
            if len(self.seen) < 1000:
                self.seen[body.rigid_body_name] = self.seen.get(body.rigid_body_name, 0) + 1
        return None

    def diagnose(self) -> str:
        if not self.seen:
            return f'no message held the rigid body {self.name!r}, nor any other'
        names = sorted(self.seen, key=lambda n: -self.seen[n])[:LISTED]
        return f'no message held the rigid body {self.name!r}; bodies seen: ' + ', '.join(
            f'{n!r} ({self.seen[n]} msgs)' for n in names
        )


@dataclass
class _Edge:
    """One transform of the tree: the pose of ``child`` in ``parent`` (x y z qx qy qz qw)."""

    parent: str
    static: bool
    value: tuple[float, ...]
    count: int = 1
    changed: int = 0  # times a static value was replaced by a different one


class TfChain:
    """The pose of ``child`` in ``parent`` from /tf and /tf_static messages.

    The tree is learnt as messages come (a frame has one parent, as in tf2). Once both frames
    are connected through static transforms and exactly one moving transform, each new sample
    of that moving transform is one pose of the stream (its own stamp)."""

    def __init__(self, parent: str, child: str, text: str):
        self.parent, self.child, self.text = parent, child, text
        self.edges: dict[str, _Edge] = {}
        #: The chain as factors (frame of the edge, inverted), parent side first, once found.
        self.path: list[tuple[str, bool]] | None = None
        self.moving: str | None = None  # the frame whose edge moves
        self.problem: str | None = None  # why the chain cannot give poses
        self._dirty = True
        self.early = 0  # samples of the moving link that came before the chain was complete

    # -------------------------------------------------------------- messages

    def poses(self, msg: TFMessage, static: bool) -> list[StampedPose]:
        """Learn a TFMessage's transforms; the moving link's samples it holds (raw values,
        see :meth:`finish`), as stamped poses."""
        out: list[StampedPose] = []
        for tf in msg.transforms:
            child = frame_name(tf.child_frame_id)
            parent = frame_name(tf.header.frame_id)
            t, r = tf.transform.translation, tf.transform.rotation
            value = (
                float(t.x),
                float(t.y),
                float(t.z),
                float(r.x),
                float(r.y),
                float(r.z),
                float(r.w),
            )
            edge = self.edges.get(child)
            if edge is None or edge.parent != parent or edge.static != static:
                if self.path is not None and child in dict(self.path):
                    # the tree changed under a chain already in use: keep the chain it gave
                    # (its samples are in the buffer); the change is said in the warnings
                    self.problem = self.problem or (
                        f'{child!r} changed parent or kind to {parent!r} '
                        f'({"static" if static else "moving"}) during the recording'
                    )
                    if edge is not None:
                        continue
                self.edges[child] = _Edge(parent, static, value)
                self._dirty = self._dirty or self.path is None
            else:
                edge.count += 1
                if static and value != edge.value:
                    edge.changed += 1
                edge.value = value
            if static:
                continue
            if self._dirty:
                self._find_path()
            if child == self.moving:
                out.append((_stamp(tf.header), *value))
        return out

    def _find_path(self) -> None:
        self._dirty = False
        up_a, up_b = self._ancestors(self.parent), self._ancestors(self.child)
        common = next((f for f in up_a if f in set(up_b)), None)
        if common is None:
            return
        factors = [(f, True) for f in up_a[: up_a.index(common)]]
        factors += [(f, False) for f in reversed(up_b[: up_b.index(common)])]
        moving = [f for f, _ in factors if not self.edges[f].static]
        if len(moving) != 1:
            names = ', '.join(f'{self.edges[f].parent}->{f}' for f in moving)
            self.problem = (
                'every transform between them is static: the pose never moves'
                if not moving
                else f'the chain passes {len(moving)} moving transforms ({names}): choose a '
                'pair joined by one moving transform (combining several needs interpolating '
                'them in time, which this tool does not do)'
            )
            return
        self.problem = None
        self.path, self.moving = factors, moving[0]
        self.early = self.edges[self.moving].count - 1

    def _ancestors(self, frame: str) -> list[str]:
        """The frame and its ancestors up to the root of its tree (a loop ends the walk)."""
        out, seen = [frame], {frame}
        while (edge := self.edges.get(out[-1])) is not None and edge.parent not in seen:
            out.append(edge.parent)
            seen.add(edge.parent)
        return out

    # -------------------------------------------------------------- results

    def finish(self, raw: Trajectory) -> Trajectory:
        """The stream of ``parent -> child`` poses from the buffered moving-link samples: the
        static factors before and after it composed with each sample, which is inverted when
        the chain climbs it (x_parent = L * D^(+-1) * R x_child)."""
        assert self.path is not None and self.moving is not None
        k = [f for f, _ in self.path].index(self.moving)
        left, right = self._product(self.path[:k]), self._product(self.path[k + 1 :])
        r = Rotation.from_quat(raw.q_xyzw)
        p = raw.p_xyz
        if self.path[k][1]:
            r = r.inv()
            p = -r.apply(p)
        (rl, pl), (rr, pr) = left, right
        rot = rl * r * rr
        pos = pl + rl.apply(p + r.apply(pr))
        q = rot.as_quat()
        return Trajectory.from_arrays(raw.t_ns, pos, q, name=raw.name)

    def _product(self, factors: list[tuple[str, bool]]) -> tuple[Rotation, Floats]:
        rot, pos = Rotation.identity(), np.zeros(3)
        for frame, inverted in factors:
            v = self.edges[frame].value
            r, p = Rotation.from_quat(v[3:]), np.asarray(v[:3])
            if inverted:
                r = r.inv()
                p = -r.apply(p)
            pos = pos + rot.apply(p)
            rot = rot * r
        return rot, pos

    def describe(self) -> list[str]:
        """The chain, parent side first, as 'parent->child (moving|static[, inverted])'."""
        return [
            f'{self.edges[f].parent}->{f} ({"static" if self.edges[f].static else "moving"}'
            f'{", inverted" if inv else ""})'
            for f, inv in (self.path or [])
        ]

    def warnings(self) -> list[str]:
        """What the user should know about the chain the poses came from."""
        out = []
        if self.path is not None:
            changed = [f for f, _ in self.path if self.edges[f].changed]
            if changed:
                out.append(
                    f'{self.text}: the static transform(s) '
                    + ', '.join(
                        f'{self.edges[f].parent}->{f} ({self.edges[f].changed} changes)'
                        for f in changed
                    )
                    + ' changed during the recording; the last value is used'
                )
            if self.problem:
                out.append(f'{self.text}: {self.problem}; the chain found first is kept')
            if self.early:
                out.append(
                    f'{self.text}: {self.early} moving transform(s) came before the '
                    'chain was complete and were skipped'
                )
        return out

    def diagnose(self) -> str:
        """Why no pose came out: the frames seen and what joins them."""
        if self.path is None and self.edges:
            self._find_path()  # a bag of static transforms only never triggered the search
        if self.problem and self.path is None:
            return f'{self.parent!r} to {self.child!r}: {self.problem}'
        if not self.edges:
            return 'no transform was received'
        moving = sorted(
            (f for f, e in self.edges.items() if not e.static), key=lambda f: -self.edges[f].count
        )
        static = sorted(f for f, e in self.edges.items() if e.static)
        missing = [
            f
            for f in (self.parent, self.child)
            if f not in self.edges and all(e.parent != f for e in self.edges.values())
        ]
        why = (
            f'no frame {", ".join(map(repr, missing))} in the tf tree'
            if missing
            else f'{self.parent!r} and {self.child!r} are in different tf trees'
        )
        return (
            f'{why}; moving transforms: '
            + (
                ', '.join(
                    f'{self.edges[f].parent}.{f} ({self.edges[f].count} msgs)'
                    for f in moving[:LISTED]
                )
                or 'none'
            )
            + '; static transforms: '
            + (', '.join(f'{self.edges[f].parent}.{f}' for f in static[:LISTED]) or 'none')
        )
