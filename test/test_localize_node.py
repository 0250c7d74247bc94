"""The running graph localizes a replayed repeat drive on the map of its teach drive.

`skynav launch` starts every node (skyline, sh, localize with the map), `skynav replay` plays the
synthetic repeat drive, and the place matches are checked against the ground-truth positions. Offline
(`skynav eval localization`) every match of this pair is accepted and correct; live, a camera frame
may occasionally be dropped by the best-effort camera subscription, which the bounds allow for.
"""

import signal
import time
from pathlib import Path

import numpy as np

from skynav_bringup.bag import open_bag
from skynav_bringup.images import stamp_ns
from skynav_bringup.testing import run_skynav, start_skynav, wait_text
from skynav_localize.evaluation import correct_matches
from skynav_localize.store import MapStore

BAGS = Path(__file__).parents[1] / 'bags'


def test_replayed_repeat_drive_is_localized_on_the_teach_map(tmp_path, ros_context):
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.node import Node
    from skynav_msgs.msg import PlaceMatch

    map_file = tmp_path / 'garden.db'
    built = run_skynav('map', 'build', str(BAGS / 'synthetic_garden_teach.mcap'), '--out', str(map_file))
    assert built.returncode == 0, built.stderr
    params = tmp_path / 'params.yaml'
    params.write_text(f'localize:\n  ros__parameters:\n    map: {map_file}\n')
    repeat = BAGS / 'synthetic_garden_repeat.mcap'
    truth = {}
    with open_bag(repeat) as bag:
        for raw in bag.messages(['/ground_truth/pose']):
            message = bag.deserialize(raw)
            p = message.pose.position
            truth[stamp_ns(message.header)] = np.array([p.x, p.y, p.z])

    node = Node('localize_test', context=ros_context)
    executor = SingleThreadedExecutor(context=ros_context)
    executor.add_node(node)
    matches = {}
    node.create_subscription(PlaceMatch, '/localization/match', lambda m: matches.__setitem__(stamp_ns(m.header), m),
                             100)
    launch = start_skynav('launch', '--params', str(params))
    try:
        deadline = time.monotonic() + 60
        while node.count_publishers('/localization/match') == 0 and time.monotonic() < deadline:
            executor.spin_once(timeout_sec=0.1)
        replay = start_skynav('replay', str(repeat), '--rate', '1', '--wait-for-subscribers', '30',
                              '--topics', '/camera/uv/image_raw', '/camera/green/image_raw', '/camera/uv/camera_info')
        while replay.poll() is None:
            executor.spin_once(timeout_sec=0.05)
        assert replay.returncode == 0, replay.stderr.read()
        deadline = time.monotonic() + 10
        while len(matches) < len(truth) and time.monotonic() < deadline:
            executor.spin_once(timeout_sec=0.05)
    finally:
        launch.send_signal(signal.SIGINT)
        out, err = launch.communicate(timeout=60)
        executor.shutdown()
        node.destroy_node()
    assert launch.returncode == 0, out + err
    assert len(matches) >= 0.95 * len(truth), f'{len(matches)} matches for {len(truth)} frames'
    store = MapStore.open(map_file)
    stamps = sorted(matches)
    matched = np.array([matches[s].index for s in stamps])
    accepted = np.array([matches[s].accepted for s in stamps])
    correct = correct_matches(matched, np.stack([truth[s] for s in stamps]), store.positions(), 1.0)
    store.close()
    assert accepted.mean() >= 0.9
    assert correct[accepted].all()  # precision 100 %
    assert all(matches[s].map_name == 'garden' for s in stamps)
