"""Poses out of many-pose messages: /tf pairs through static chains, and mocap4r2 rigid bodies.

The chain arithmetic is checked against 4x4 matrices on random trees; the bags (written with
rosbags, as drivers record them) must give the very result of the same poses on plain pose
topics, and every malformed selection must say what the bag holds instead."""

from __future__ import annotations

import json
import sqlite3
from pathlib import Path

import numpy as np
import pytest
from bag_layouts import (
    RIGID_BODIES_TOPIC,
    TF_SELECTORS,
    write_rigid_bodies_recording,
    write_tf_recording,
)
from conftest import recording, run_main
from scipy.spatial.transform import Rotation

from handeye_ros.core.errors import ConfigError
from handeye_ros.core.trajectory import Trajectory
from handeye_ros.formats.bag import (
    MOCAP4R2_MSGS,
    BagWriter,
    _typestore,
    pose_messages,
    write_recording,
)
from handeye_ros.formats.messages import transform_stamped
from handeye_ros.stream import Recorder, StreamConfig
from handeye_ros.stream.sources import TfChain, parse_selector

pytestmark = pytest.mark.slow  # subprocesses, bags, evo, Dask or real data: seconds each

TF = 'tf2_msgs/msg/TFMessage'
RB = 'mocap4r2_msgs/msg/RigidBodies'


def _matrix(p, q) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = Rotation.from_quat(q).as_matrix()
    T[:3, 3] = p
    return T


def _random_pose(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    return rng.normal(size=3), Rotation.random(random_state=rng).as_quat()


@pytest.fixture(scope='module')
def store():
    return _typestore()


@pytest.fixture(scope='module')
def rec():
    return recording(seed=4, level=3.0, duration_s=40.0)


def _tf_msg(store, *transforms):
    return store.types[TF](transforms=list(transforms))


# ------------------------------------------------------------------ the chain arithmetic


@pytest.mark.parametrize(
    ('parent', 'child'), [('e', 'c'), ('c', 'e'), ('a', 'b'), ('b', 'a'), ('world', 'c')]
)
def test_chain_equals_matrix_products(store, parent: str, child: str) -> None:
    """world -> a (static) -> b (moving) -> c (static); world -> d -> e (static): every pair
    across the moving link, in either direction, is the product of the edge matrices."""
    rng = np.random.default_rng(7)
    statics = {
        ('world', 'a'): _random_pose(rng),
        ('b', 'c'): _random_pose(rng),
        ('world', 'd'): _random_pose(rng),
        ('d', 'e'): _random_pose(rng),
    }
    chain = TfChain(parent, child, f'/tf:{parent}.{child}')
    chain.poses(
        _tf_msg(
            store,
            *(transform_stamped(store.types, 0, pa, ch, *v) for (pa, ch), v in statics.items()),
        ),
        static=True,
    )
    moving = [_random_pose(rng) for _ in range(20)]
    raw = []
    for k, (p, q) in enumerate(moving):
        raw += chain.poses(
            _tf_msg(store, transform_stamped(store.types, 10**9 + k, 'a', 'b', p, q)), static=False
        )
    assert len(raw) == len(moving)
    arr = np.array(raw)
    out = chain.finish(
        Trajectory.from_arrays(arr[:, 0].astype(np.int64), arr[:, 1:4], arr[:, 4:], name='x')
    )
    world = {'world': lambda T: np.eye(4), 'a': lambda T: _matrix(*statics['world', 'a'])}
    world['b'] = lambda T: world['a'](T) @ T
    world['c'] = lambda T: world['b'](T) @ _matrix(*statics['b', 'c'])
    world['d'] = lambda T: _matrix(*statics['world', 'd'])
    world['e'] = lambda T: world['d'](T) @ _matrix(*statics['d', 'e'])
    for k, (p, q) in enumerate(moving):
        T = _matrix(p, q)
        want = np.linalg.inv(world[parent](T)) @ world[child](T)
        np.testing.assert_allclose(_matrix(out.p_xyz[k], out.q_xyzw[k]), want, atol=1e-12)
    assert out.t_ns[0] == 10**9


def test_chain_refuses_what_it_cannot_give(store) -> None:
    rng = np.random.default_rng(1)
    two = TfChain('map', 'base', '/tf:map.base')
    for k in range(3):
        assert (
            two.poses(
                _tf_msg(
                    store,
                    transform_stamped(store.types, k + 1, 'map', 'odom', *_random_pose(rng)),
                    transform_stamped(store.types, k + 1, 'odom', 'base', *_random_pose(rng)),
                ),
                static=False,
            )
            == []
        )
    assert 'passes 2 moving transforms (map->odom, odom->base)' in two.diagnose()
    still = TfChain('world', 'cam', '/tf:world.cam')
    still.poses(
        _tf_msg(store, transform_stamped(store.types, 0, 'world', 'cam', *_random_pose(rng))),
        static=True,
    )
    still.poses(
        _tf_msg(store, transform_stamped(store.types, 1, 'world', 'other', *_random_pose(rng))),
        static=False,
    )
    assert 'never moves' in still.diagnose()
    apart = TfChain('world', 'imu', '/tf:world.imu')
    apart.poses(
        _tf_msg(store, transform_stamped(store.types, 1, 'odom', 'imu', *_random_pose(rng))),
        static=False,
    )
    assert "no frame 'world'" in apart.diagnose() and 'odom.imu (1 msgs)' in apart.diagnose()
    for bad in ('/tf:world', '/tf:.imu', '/tf:a.a'):
        with pytest.raises(ConfigError):
            parse_selector(bad).frames()
    with pytest.raises(ConfigError, match='static topic'):
        parse_selector('/tf:a.b:tf_static')
    assert parse_selector('/tf:world.base.link').frames() == ('world', 'base.link')
    assert parse_selector('/tf:/world.marker:/my_static').topics == ('/tf', '/my_static')


# ------------------------------------------------------------------ bags


def _tf_bag(path: Path, rec, storage: str = 'mcap', slash: str = '') -> tuple[Path, dict]:
    """The hand as world -> rig (moving) -> marker (static, logged after the first moving
    samples, as a recorder started before the static broadcaster does), the eye as the
    inverse link imu -> odom (moving; the selector odom.imu climbs it); both on /tf."""
    write_tf_recording(path, rec.hand, rec.eye, storage, slash)
    return path, {'--hand-topic': TF_SELECTORS['hand'], '--eye-topic': TF_SELECTORS['eye']}


def _run(bag: Path, *args: str) -> dict:
    res = run_main('--bag', bag, '--json', '--no-evaluation', *args)
    assert res.returncode == 0, res.stderr
    assert 'Traceback' not in res.stderr
    return json.loads(res.stdout)


def _same(a: dict, b: dict) -> None:
    assert a['time_offset'] == pytest.approx(b['time_offset'], abs=1e-9)
    np.testing.assert_allclose(a['extrinsic']['matrix'], b['extrinsic']['matrix'], atol=1e-9)


@pytest.fixture(scope='module')
def plain(tmp_path_factory, rec) -> dict:
    path = tmp_path_factory.mktemp('plain') / 'plain'
    write_recording(
        path,
        [
            ('/mocap/pose', 'PoseStamped', rec.hand, 'mocap', 'marker'),
            ('/vio/odom', 'Odometry', rec.eye, 'odom', 'imu'),
        ],
    )
    return _run(path)


@pytest.mark.parametrize(('storage', 'slash'), [('mcap', ''), ('ros1', '/')])
def test_tf_bag_gives_the_plain_result(
    tmp_path: Path, rec, plain: dict, storage: str, slash: str
) -> None:
    bag, topics = _tf_bag(
        tmp_path / ('tf.bag' if storage == 'ros1' else 'tf'), rec, storage, slash
    )
    d = _run(bag, *(x for kv in topics.items() for x in kv))
    _same(d, plain)
    assert d['streams']['hand']['received'] == len(rec.hand)
    assert d['streams']['hand']['tf_chain'] == ['world->rig (moving)', 'rig->marker (static)']
    assert d['streams']['eye']['tf_chain'] == ['imu->odom (moving, inverted)']
    assert not [w for w in d['warnings'] if '/tf' in w], d['warnings']


def test_tf_selection_errors_list_what_the_bag_holds(tmp_path: Path, rec) -> None:
    bag, _ = _tf_bag(tmp_path / 'tf', rec)
    res = run_main(
        '--bag', bag, '--hand-topic', '/tf:world.nothing', '--eye-topic', '/tf:odom.imu'
    )
    assert res.returncode == 1 and 'Traceback' not in res.stderr, res.stderr
    assert "no frame 'nothing'" in res.stderr and 'world.rig' in res.stderr, res.stderr
    res = run_main('--bag', bag, '--hand-topic', '/tf', '--eye-topic', '/tf:odom.imu')
    assert res.returncode == 1 and 'PARENT.CHILD' in res.stderr, res.stderr
    assert '/tf:world.rig' in res.stderr and '/tf:imu.odom' in res.stderr, res.stderr
    res = run_main('--bag', bag)
    assert res.returncode == 1 and '/tf (tf2_msgs/msg/TFMessage' in res.stderr, res.stderr
    res = run_main('--bag', bag, '--hand-topic', '/tf:odom.imu', '--eye-topic', '/tf:odom.imu')
    assert res.returncode == 1 and 'both read /tf' in res.stderr, res.stderr


def _old_package_bag(path: Path, rec) -> Path:
    """The hand as the body 'rig' of mocap_msgs/RigidBodies (mocap4r2's name before the
    rename), whose definition only the bag holds."""
    from rosbags.typesys import get_types_from_msg

    store = _typestore()
    for name, text in MOCAP4R2_MSGS.items():
        store.register(
            get_types_from_msg(
                text.replace('mocap4r2_msgs', 'mocap_msgs'),
                name.replace('mocap4r2_msgs', 'mocap_msgs'),
            )
        )
    T = store.types
    with BagWriter(path) as w:
        w.store = store
        items = [
            (t, 1, '/vio/odom', 'nav_msgs/msg/Odometry', m)
            for t, m in pose_messages(store, rec.eye, 'Odometry', 'odom', 'imu')
        ]
        for t, m in pose_messages(store, rec.hand, 'PoseStamped', 'mocap', 'rig'):
            body = T['mocap_msgs/msg/RigidBody'](rigid_body_name='rig', markers=[], pose=m.pose)
            items.append(
                (
                    t,
                    0,
                    RIGID_BODIES_TOPIC,
                    'mocap_msgs/msg/RigidBodies',
                    T['mocap_msgs/msg/RigidBodies'](
                        header=m.header, frame_number=0, rigidbodies=[body]
                    ),
                )
            )
        items.sort(key=lambda x: (x[0], x[1]))
        for t, _, topic, mt, m in items:
            w.write(topic, mt, t, m)
    return path


@pytest.mark.parametrize('case', ['mcap', 'sqlite3 without definitions', 'mocap_msgs'])
def test_rigid_body_by_name(tmp_path: Path, rec, plain: dict, case: str) -> None:
    storage = 'mcap' if case != 'sqlite3 without definitions' else 'sqlite3'
    package = 'mocap_msgs' if case == 'mocap_msgs' else 'mocap4r2_msgs'
    bag = tmp_path / 'bodies'
    if package == 'mocap_msgs':
        _old_package_bag(bag, rec)
    else:
        write_rigid_bodies_recording(bag, rec.hand, rec.eye, storage)
    if storage == 'sqlite3':
        # as ROS 2 Humble records: no message definitions in the bag
        db = next(bag.glob('*.db3'))
        with sqlite3.connect(db) as con:
            con.execute('DELETE FROM message_definitions')
    d = _run(bag, '--hand-topic', '/mocap/rigid_bodies:rig')
    _same(d, plain)
    assert d['streams']['hand']['type'] == f'{package}/msg/RigidBodies'


def test_rigid_body_lost_frames_are_counted_and_names_listed(
    tmp_path: Path, rec, plain: dict
) -> None:
    bag = tmp_path / 'bodies'
    write_rigid_bodies_recording(bag, rec.hand, rec.eye, lost_every=50)
    d = _run(bag, '--hand-topic', '/mocap/rigid_bodies:rig')
    lost = len(range(25, len(rec.hand), 50))
    assert d['streams']['hand']['rejected']['not_in_message'] == lost
    assert d['streams']['hand']['buffered'] == len(rec.hand) - lost
    assert any(f'{lost} not in message' in w for w in d['warnings']), d['warnings']
    assert abs(d['time_offset'] - plain['time_offset']) < 1e-3
    res = run_main('--bag', bag, '--hand-topic', '/mocap/rigid_bodies:drone')
    assert res.returncode == 1 and 'Traceback' not in res.stderr, res.stderr
    assert "no message held the rigid body 'drone'" in res.stderr
    assert "'wand'" in res.stderr and "'rig'" in res.stderr, res.stderr
    res = run_main('--bag', bag, '--hand-topic', '/mocap/rigid_bodies')
    assert res.returncode == 1 and '/mocap/rigid_bodies:rig' in res.stderr, res.stderr
    res = run_main(
        '--bag', bag, '--hand-topic', '/mocap/rigid_bodies:rig', '--eye-topic', '/vio/odom:imu'
    )
    assert res.returncode == 1 and 'one pose per message' in res.stderr, res.stderr


def test_recorder_feeds_one_tf_message_to_both_streams(store) -> None:
    """Live, the node hands each /tf message to the Recorder once per stream it feeds."""
    rec = Recorder(StreamConfig(hand_topic='/tf:world.marker', eye_topic='/tf:odom.imu'))
    for s in ('hand', 'eye'):
        rec.set_type(s, 'TFMessage')
    assert rec.routes() == {
        '/tf': [('hand', False), ('eye', False)],
        '/tf_static': [('hand', True), ('eye', True)],
    }
    rng = np.random.default_rng(2)
    for k in range(5):
        msg = _tf_msg(
            store,
            transform_stamped(store.types, k + 1, 'world', 'marker', *_random_pose(rng)),
            transform_stamped(store.types, k + 1, 'odom', 'imu', *_random_pose(rng)),
        )
        for stream, static in rec.routes()['/tf']:
            rec.add(stream, msg, static)
    assert rec.stats()['hand'].stored == rec.stats()['eye'].stored == 5
