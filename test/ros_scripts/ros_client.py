"""A client process: call Trigger services and read the node's latched topics; prints JSON.

Usage: ros_client.py call SERVICE [SERVICE ...]      (each called in turn)
       ros_client.py serve                            (the same for each JSON list of
                                                       services on stdin, a JSON line each)
       ros_client.py concurrent SERVICE SERVICE ...  (all sent at once, answers in order)
       ros_client.py staggered SERVICE SERVICE ...   (sent 0.3 s apart, without waiting)
       ros_client.py latched                          (the latched outputs of /calibrator
                                                       and the result's /diagnostics status)
       ros_client.py param NAME:=VALUE ...            (set /calibrator's parameters; YAML
                                                       values)
       ros_client.py tf_static                        (the latched /tf_static; needs tf2_msgs)
       ros_client.py paths                            (the latched eye and ground-truth paths)
       ros_client.py status SECONDS [UNTIL ...]       (every ~/status of /calibrator and when
                                                       each new extrinsic came, for SECONDS;
                                                       or until each regex UNTIL has matched a
                                                       status's message or value, then LINGER_S)
"""

from __future__ import annotations

import json
import re
import sys
import time

import rclpy
import yaml
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PoseWithCovarianceStamped, TransformStamped
from rclpy.client import Client
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.parameter_client import AsyncParameterClient
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import TimeReference
from std_msgs.msg import Float64
from std_srvs.srv import Trigger

TIMEOUT_S = 60.0
#: How long status mode goes on once its UNTIL regexes have matched: three status periods of
#: the tests (0.5 s), so that a state that should hold, or should not follow, is seen.
LINGER_S = 1.5


def call(
    node: Node,
    names: list[str],
    concurrent: bool,
    gap_s: float = 0.0,
    made: dict[str, Client] | None = None,
) -> list[dict]:
    """Call the services; ``made``: clients kept from earlier calls, by service (serve mode)."""
    made = {} if made is None else made
    for n in names:
        if n not in made:
            made[n] = node.create_client(Trigger, n)
    clients = [made[n] for n in names]
    for c, n in zip(clients, names, strict=True):
        if not c.wait_for_service(timeout_sec=TIMEOUT_S):
            return [{'error': f'service {n} not available'}]
    out = []
    if concurrent:
        futures = []
        for c in clients:
            if futures and gap_s:
                end = time.monotonic() + gap_s
                while time.monotonic() < end:
                    rclpy.spin_once(node, timeout_sec=0.05)
            futures.append(c.call_async(Trigger.Request()))
        for f in futures:
            rclpy.spin_until_future_complete(node, f, timeout_sec=TIMEOUT_S)
        return [{'success': f.result().success, 'message': f.result().message} for f in futures]
    for c in clients:
        f = c.call_async(Trigger.Request())
        print(f'sent {c.srv_name}', file=sys.stderr, flush=True)  # a test may wait for it
        rclpy.spin_until_future_complete(node, f, timeout_sec=TIMEOUT_S)
        out.append({'success': f.result().success, 'message': f.result().message})
    return out


def latched(node: Node) -> dict:
    qos = QoSProfile(
        depth=1,
        reliability=ReliabilityPolicy.RELIABLE,
        durability=DurabilityPolicy.TRANSIENT_LOCAL,
    )
    got: dict = {}
    node.create_subscription(
        TransformStamped, '/calibrator/extrinsic', lambda m: got.__setitem__('extrinsic', m), qos
    )
    node.create_subscription(
        Float64, '/calibrator/time_offset', lambda m: got.__setitem__('time_offset', m.data), qos
    )
    node.create_subscription(
        PoseWithCovarianceStamped,
        '/calibrator/extrinsic_with_covariance',
        lambda m: got.__setitem__('covariance', list(m.pose.covariance)),
        qos,
    )

    node.create_subscription(
        TimeReference,
        '/calibrator/time_reference',
        lambda m: got.__setitem__('time_reference', m),
        qos,
    )

    def on_diagnostics(msg: DiagnosticArray) -> None:
        for st in msg.status:
            values = {kv.key: kv.value for kv in st.values}
            if st.name.endswith(': result'):
                got['diagnostics'] = {
                    'level': int.from_bytes(st.level, 'little')
                    if isinstance(st.level, bytes)
                    else int(st.level),
                    'message': st.message,
                    'values': values,
                    'verdict': values.get('verdict'),
                    'reasons': values.get('reasons', ''),
                }

    node.create_subscription(DiagnosticArray, '/diagnostics', on_diagnostics, 10)
    deadline = time.monotonic() + 10.0
    while len(got) < 5 and time.monotonic() < deadline:
        rclpy.spin_once(node, timeout_sec=0.1)
    if 'extrinsic' in got:
        m = got['extrinsic']
        t, r = m.transform.translation, m.transform.rotation
        got['extrinsic'] = {
            'parent': m.header.frame_id,
            'child': m.child_frame_id,
            'stamp_ns': m.header.stamp.sec * 10**9 + m.header.stamp.nanosec,
            'translation': [t.x, t.y, t.z],
            'rotation': [r.x, r.y, r.z, r.w],
        }
    if 'time_reference' in got:
        m = got['time_reference']
        s, r = m.header.stamp, m.time_ref
        got['time_reference'] = {
            'offset_ns': (s.sec - r.sec) * 10**9 + s.nanosec - r.nanosec,
            'stamp_ns': s.sec * 10**9 + s.nanosec,
            'frame_id': m.header.frame_id,
            'source': m.source,
        }
    return got


def tf_static(node: Node) -> list[dict]:
    from tf2_msgs.msg import TFMessage

    qos = QoSProfile(
        depth=100,
        reliability=ReliabilityPolicy.RELIABLE,
        durability=DurabilityPolicy.TRANSIENT_LOCAL,
    )
    got: list = []
    node.create_subscription(TFMessage, '/tf_static', got.append, qos)
    deadline = time.monotonic() + 20.0
    while not got and time.monotonic() < deadline:
        rclpy.spin_once(node, timeout_sec=0.1)
    return [
        {
            'parent': t.header.frame_id,
            'child': t.child_frame_id,
            'translation': [
                t.transform.translation.x,
                t.transform.translation.y,
                t.transform.translation.z,
            ],
        }
        for m in got
        for t in m.transforms
    ]


def status(node: Node, seconds: float, until: list[str]) -> dict:
    """The statuses and extrinsics for ``seconds`` at most; once every regex of ``until``
    has matched (a message or a value of some status), LINGER_S more, so that what follows a
    state is seen too."""
    from diagnostic_msgs.msg import DiagnosticStatus

    t0 = time.monotonic()
    got: dict = {'status': [], 'extrinsic': [], 'until_met': None}
    pending = [re.compile(u) for u in until]

    def on_status(m: DiagnosticStatus) -> None:
        got['status'].append(
            {
                't': time.monotonic() - t0,
                'level': int.from_bytes(m.level, 'little')
                if isinstance(m.level, bytes)
                else int(m.level),
                'message': m.message,
                'values': {kv.key: kv.value for kv in m.values},
            }
        )
        texts = [m.message, *(kv.value for kv in m.values)]
        pending[:] = [u for u in pending if not any(u.search(t) for t in texts)]
        if until and not pending and got['until_met'] is None:
            got['until_met'] = time.monotonic() - t0

    qos = QoSProfile(
        depth=1,
        reliability=ReliabilityPolicy.RELIABLE,
        durability=DurabilityPolicy.TRANSIENT_LOCAL,
    )
    node.create_subscription(DiagnosticStatus, '/calibrator/status', on_status, 10)
    node.create_subscription(
        TransformStamped,
        '/calibrator/extrinsic',
        lambda m: got['extrinsic'].append(time.monotonic() - t0),
        qos,
    )
    end = t0 + seconds
    while time.monotonic() < end:
        rclpy.spin_once(node, timeout_sec=0.05)
        if got['until_met'] is not None:
            end = min(end, t0 + got['until_met'] + LINGER_S)
    return got


def paths(node: Node) -> dict:
    from nav_msgs.msg import Path

    qos = QoSProfile(
        depth=1,
        reliability=ReliabilityPolicy.RELIABLE,
        durability=DurabilityPolicy.TRANSIENT_LOCAL,
    )
    got: dict = {}
    for name in ('eye_path', 'ground_truth_path'):
        node.create_subscription(
            Path, f'/calibrator/{name}', lambda m, n=name: got.__setitem__(n, m), qos
        )
    deadline = time.monotonic() + 20.0
    while len(got) < 2 and time.monotonic() < deadline:
        rclpy.spin_once(node, timeout_sec=0.1)
    return {
        n: {
            'frame': m.header.frame_id,
            'stamps': [p.header.stamp.sec * 10**9 + p.header.stamp.nanosec for p in m.poses],
            'xyz': [[p.pose.position.x, p.pose.position.y, p.pose.position.z] for p in m.poses],
        }
        for n, m in got.items()
    }


def set_parameters(node: Node, assignments: list[str]) -> list[dict]:
    client = AsyncParameterClient(node, '/calibrator')
    if not client.wait_for_services(timeout_sec=TIMEOUT_S):
        return [{'error': 'parameter services of /calibrator not available'}]
    params = [
        Parameter(name, value=yaml.safe_load(value))
        for name, value in (a.split(':=', 1) for a in assignments)
    ]
    f = client.set_parameters(params)
    rclpy.spin_until_future_complete(node, f, timeout_sec=TIMEOUT_S)
    return [{'success': r.successful, 'message': r.reason} for r in f.result().results]


def serve(node: Node) -> None:
    """call mode for each line of stdin (a JSON list of services) until it ends, an answer
    line each. Its clients are made once: a new client, in this process or in a new one,
    waits up to 3 s for DDS discovery."""
    made: dict[str, Client] = {}
    for line in sys.stdin:
        print(json.dumps(call(node, json.loads(line), concurrent=False, made=made)), flush=True)


def main() -> int:
    rclpy.init()
    node = Node('test_client')
    mode, names = sys.argv[1], sys.argv[2:]
    if mode == 'latched':
        out = latched(node)
    elif mode == 'tf_static':
        out = tf_static(node)
    elif mode == 'paths':
        out = paths(node)
    elif mode == 'status':
        out = status(node, float(names[0]), names[1:])
    elif mode == 'param':
        out = set_parameters(node, names)
    elif mode == 'serve':
        serve(node)
        out = []
    else:
        out = call(
            node,
            names,
            concurrent=mode in ('concurrent', 'staggered'),
            gap_s=0.3 if mode == 'staggered' else 0.0,
        )
    print(json.dumps(out), flush=True)
    node.destroy_node()
    rclpy.try_shutdown()
    return 0


if __name__ == '__main__':
    sys.exit(main())
