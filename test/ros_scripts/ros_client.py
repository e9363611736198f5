"""A client process: call Trigger services and read the node's latched topics; prints JSON.

Usage: ros_client.py call SERVICE [SERVICE ...]      (each called in turn)
       ros_client.py concurrent SERVICE SERVICE ...  (all sent at once, answers in order)
       ros_client.py staggered SERVICE SERVICE ...   (sent 0.3 s apart, without waiting)
       ros_client.py latched                          (/calibrator/extrinsic and time_offset,
                                                       the result's /diagnostics status)
"""

from __future__ import annotations

import json
import sys
import time

import rclpy
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PoseWithCovarianceStamped, TransformStamped
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from std_msgs.msg import Float64
from std_srvs.srv import Trigger

TIMEOUT_S = 60.0


def call(node: Node, names: list[str], concurrent: bool, gap_s: float = 0.0) -> list[dict]:
    clients = [node.create_client(Trigger, n) for n in names]
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
        rclpy.spin_until_future_complete(node, f, timeout_sec=TIMEOUT_S)
        out.append({'success': f.result().success, 'message': f.result().message})
    return out


def latched(node: Node) -> dict:
    qos = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                     durability=DurabilityPolicy.TRANSIENT_LOCAL)
    got: dict = {}
    node.create_subscription(TransformStamped, '/calibrator/extrinsic',
                             lambda m: got.__setitem__('extrinsic', m), qos)
    node.create_subscription(Float64, '/calibrator/time_offset',
                             lambda m: got.__setitem__('time_offset', m.data), qos)
    node.create_subscription(PoseWithCovarianceStamped, '/calibrator/extrinsic_with_covariance',
                             lambda m: got.__setitem__('covariance', list(m.pose.covariance)),
                             qos)

    def on_diagnostics(msg: DiagnosticArray) -> None:
        for st in msg.status:
            values = {kv.key: kv.value for kv in st.values}
            if st.name.endswith(': result') and 'verdict' in values:
                got['diagnostics'] = {'level': int.from_bytes(st.level, 'little')
                                      if isinstance(st.level, bytes) else int(st.level),
                                      'verdict': values['verdict'],
                                      'reasons': values.get('reasons', '')}
    node.create_subscription(DiagnosticArray, '/diagnostics', on_diagnostics, 10)
    deadline = time.monotonic() + 10.0
    while len(got) < 4 and time.monotonic() < deadline:
        rclpy.spin_once(node, timeout_sec=0.1)
    if 'extrinsic' in got:
        m = got['extrinsic']
        t, r = m.transform.translation, m.transform.rotation
        got['extrinsic'] = {'parent': m.header.frame_id, 'child': m.child_frame_id,
                            'translation': [t.x, t.y, t.z], 'rotation': [r.x, r.y, r.z, r.w]}
    return got


def main() -> int:
    rclpy.init()
    node = Node('test_client')
    mode, names = sys.argv[1], sys.argv[2:]
    if mode == 'latched':
        out = latched(node)
    else:
        out = call(node, names, concurrent=mode in ('concurrent', 'staggered'),
                   gap_s=0.3 if mode == 'staggered' else 0.0)
    print(json.dumps(out), flush=True)
    node.destroy_node()
    rclpy.try_shutdown()
    return 0


if __name__ == '__main__':
    sys.exit(main())
