# SPDX-License-Identifier: Apache-2.0
"""A recording killed with -9 is recovered by `skynav bag recover` to within one chunk of what was received.

The recorder is skynav's own (Recorder into BagWriter, as `skynav record`
runs them) in a child process that also prints how many messages it has
received and when; a bundled bag replays into it through DDS. After RECORD_FOR
seconds of receiving it is killed with SIGKILL: no footer, no index, the
pending chunk lost.
"""

from __future__ import annotations

import re
import signal
import subprocess
import sys

from skynav_core.names import GREEN_IMAGE, GROUND_TRUTH_POSE, UV_CAMERA_INFO, UV_IMAGE
from skynav_core.recording.mcapfile import CHUNK_PERIOD
from skynav_testing import BAGS, run_skynav, start_skynav, wait_text

RECORD_FOR = 5.0  # s of receiving before the kill
TOPICS = [UV_IMAGE, GREEN_IMAGE, UV_CAMERA_INFO, GROUND_TRUTH_POSE]
RECORDER = """
import sys, time
from skynav_core.recording.bag import BagWriter
from skynav_core.recording.recorder import Recorder
from skynav_core.ros import tool_node


class Counting(Recorder):
    def _on_message(self, topic, data):
        super()._on_message(topic, data)
        print(self.received, time.monotonic_ns(), flush=True)


writer = BagWriter(sys.argv[1])
with tool_node('skynav_record_killed') as (node, executor):
    recorder = Counting(node, writer, sys.argv[2:])
    print('ready', flush=True)
    while True:
        executor.spin_once(timeout_sec=0.05)
"""


def test_a_killed_recording_is_recovered_to_within_one_chunk(tmp_path):
    out = tmp_path / 'killed.mcap'
    recorder = subprocess.Popen(
        [sys.executable, '-c', RECORDER, str(out), *TOPICS], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
    )
    replay = None
    try:
        wait_text(recorder, 'ready', stream='stdout')
        # the recorder is the one reader (the default would wait 30 s for the graph's nodes, none running here)
        replay = start_skynav(
            'replay', str(BAGS / 'synthetic_garden_repeat.mcap'), '--loop', '--wait-for-subscribers', '1',
            '--topics', *TOPICS,
        )  # fmt: skip
        received = [tuple(map(int, recorder.stdout.readline().split()))]
        while received[-1][1] - received[0][1] < RECORD_FOR * 1e9:
            received.append(tuple(map(int, recorder.stdout.readline().split())))
        recorder.kill()
    finally:
        recorder.kill()
        recorder.wait()
        if replay is not None:
            replay.send_signal(signal.SIGINT)
            replay.communicate(timeout=30)
    count, last = received[-1]
    # The chunk being filled when the recorder died: at most what arrived in the last CHUNK_PERIOD.
    pending = sum(1 for _, at in received if at > last - CHUNK_PERIOD) + 1
    partial = tmp_path / '.killed.mcap.partial'
    assert partial.is_dir() and not out.exists()
    result = run_skynav('bag', 'recover', str(partial), str(tmp_path / 'recovered.mcap'))
    assert result.returncode == 0, result.stderr
    saved = int(re.search(r'saved (\d+) messages', result.stderr).group(1))
    print(f'killed after {RECORD_FOR} s: received {count}, recovered {saved} (one chunk: up to {pending})')
    assert count - pending <= saved <= count, result.stderr
    info = run_skynav('info', str(tmp_path / 'recovered.mcap'))
    assert info.returncode == 0 and f'Messages:          {saved}' in info.stdout, info.stderr
