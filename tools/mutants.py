# SPDX-License-Identifier: Apache-2.0
"""Put realistic bugs into the code one at a time and show that each one fails a test (mutation testing by hand).

Each mutation is an exact source patch (a string that must occur once in one file, and its replacement) with the
tests that should catch it. For each, the file is patched in place, those tests run (pytest, in a subprocess), and
the original bytes and modification time are written back whatever happens (Ctrl-C and SIGTERM included); the
script refuses to start when a file it patches has uncommitted changes, so `git checkout -- FILE` is always a safe
way back too. Bytecode of a mutant is never cached (PYTHONDONTWRITEBYTECODE). First the tests run once without any
mutation and must pass, so that a failure under a mutation is the mutation's doing.

    .venv/bin/python tools/mutants.py             # every mutation; prints a table, exits 1 if any survives
    .venv/bin/python tools/mutants.py --list      # the mutations and their tests
    .venv/bin/python tools/mutants.py NAME ...    # only these
"""

from __future__ import annotations

import argparse
import os
import re
import signal
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SHOWN_TESTS = 2  # failed tests named per mutation in the table


@dataclass(frozen=True)
class Mutation:
    """One bug: replace `old` (occurring exactly once in `path`) by `new`; `tests` should then fail."""

    name: str
    path: str  # relative to the repository root
    old: str
    new: str
    tests: tuple[str, ...]  # pytest node ids or paths, relative to the repository root
    what: str  # the bug, in a few words


MUTATIONS = (
    Mutation(
        'map-commit-on-failure',
        'skynav_core/skynav_core/maps/writer.py',
        """            except BaseException:
                self._db.execute('ROLLBACK')""",
        """            except BaseException:
                self._db.execute('COMMIT')""",
        ('skynav_core/test/test_maps.py',),
        "MapStore's transaction commits a failed write instead of rolling it back",
    ),
    Mutation(
        'sector-fallback-from-neighbour',
        'skynav_skyline/skynav_skyline/segment.py',
        'thresholds = np.interp(np.arange(count), good, own.threshold[good], period=count)',
        'thresholds = np.interp(np.arange(count), good, own.threshold[(good + 1) % count], period=count)',
        ('skynav_skyline/test/test_segment.py',),
        "each bimodal sector's threshold taken from the next sector's split",
    ),
    Mutation(
        'sector-threshold-from-neighbour',
        'skynav_skyline/skynav_skyline/segment.py',
        'contrast, self._row.sectors(p.sectors), np.asarray(threshold) - margin',
        'contrast, self._row.sectors(p.sectors), np.roll(threshold, 1) - margin',
        ('skynav_skyline/test/test_structure.py', 'skynav_skyline/test/test_segment.py'),
        "the hole filling's 'clearly ground' test takes each sector's threshold from its neighbour",
    ),
    Mutation(
        'localize-forgets-sequence',
        'skynav_localize/skynav_localize/node.py',
        'if self.localizer is not None and self.last_stamp >= 0 and stamp - self.last_stamp > SEQUENCE_GAP_NS:',
        'if self.localizer is not None:',
        ('skynav_localize/test/test_node.py',),
        'the live localize node resets its sequence history every frame',
    ),
    Mutation(
        'warping-compass-inverted',
        'skynav_warping/skynav_warping/node.py',
        'rotation = np.array([q.x, q.y, q.z, q.w])',
        'rotation = np.array([-q.x, -q.y, -q.z, q.w])',
        ('skynav_warping/test/test_node.py',),
        'the warping node inverts the compass rotation it starts from',
    ),
    Mutation(
        'eval-ranked-by-distance',
        'skynav_localize/skynav_localize/cli/eval.py',
        """                matches.index,
                matches.score,""",
        """                matches.index,
                matches.distance,""",
        ('skynav_localize/test/test_cli.py',),
        '`skynav eval localization` ranks its precision-recall curve by the distance, not the acceptance score',
    ),
    Mutation(
        'train-swaps-thresholds',
        'skynav_skyline/skynav_skyline/cli/train.py',
        "'threshold_uv': round(float(models['uv'].threshold), 5),",
        "'threshold_uv': round(float(models['uv-green'].threshold), 5),",
        ('skynav_skyline/test/test_cli.py',),
        '`skynav skyline train` writes the UV/green threshold as the UV-only one',
    ),
    Mutation(
        'pairing-swaps-channels',
        'skynav_core/skynav_core/pairing.py',
        'return (pair_stamp, item, partner) if channel == self.channels[0] else (pair_stamp, partner, item)',
        'return (pair_stamp, item, partner) if channel != self.channels[0] else (pair_stamp, partner, item)',
        ('skynav_skyline/test/test_node.py',),
        'a pair completed by its second channel comes out with the channels swapped (UV as green)',
    ),
    Mutation(
        'unaccepted-match-chooses-snapshot',
        'skynav_core/skynav_core/snapshots.py',
        'if match.accepted and match.index >= 0:',
        'if match.index >= 0:',
        ('skynav_warping/test/test_node.py::test_target_next_aims_lookahead_snapshots_beyond_the_match',),
        'the compass and warping nodes take the snapshot of a match the localizer did not accept',
    ),
    Mutation(
        'lookahead-off-by-one',
        'skynav_core/skynav_core/snapshots.py',
        'return min(self.match.index + self.lookahead, n_snapshots - 1)',
        'return min(self.match.index + self.lookahead - 1, n_snapshots - 1)',
        ('skynav_warping/test/test_node.py::test_target_next_aims_lookahead_snapshots_beyond_the_match',),
        "target 'next' homes to the snapshot one before `lookahead` beyond the match",
    ),
    Mutation(
        'stamp-in-microseconds',
        'skynav_core/skynav_core/images.py',
        'return int(header.stamp.sec) * 1_000_000_000 + int(header.stamp.nanosec)',
        'return int(header.stamp.sec) * 1_000_000 + int(header.stamp.nanosec)',
        ('skynav_skyline/test/test_node.py', 'skynav_warping/test/test_node.py'),
        'header stamps read with seconds as a million nanoseconds',
    ),
    Mutation(
        'map-error-over-lines',
        'skynav_core/skynav_core/maps/reader.py',
        "result = [line for row in db.execute(f'PRAGMA {pragma}(3)') for line in row[0].splitlines()]",
        "result = [row[0] for row in db.execute(f'PRAGMA {pragma}(3)')]",
        ('skynav_localize/test/test_node.py::test_map_info_refuses_foreign_and_corrupt_files',),
        "a damaged map's error keeps SQLite's line breaks: more than the one line a user should get",
    ),
    Mutation(
        'amplitude-normalisation',
        'skynav_sh/skynav_sh/spectra.py',
        'return np.sqrt(np.add.reduceat(np.square(coefficients), starts, axis=-1))',
        'return np.sqrt(np.add.reduceat(np.square(coefficients), starts, axis=-1) / (2 * np.arange(degree + 1) + 1))',
        ('skynav_sh/test/test_spectra.py',),
        'the amplitude spectrum averaged over m instead of summed',
    ),
    Mutation(
        'tracking-window-end-exclusive',
        'skynav_localize/skynav_localize/localizer.py',
        'inside = (snapshots >= window[0]) & (snapshots <= window[1])',
        'inside = (snapshots >= window[0]) & (snapshots < window[1])',
        (
            'skynav_localize/test/test_localizer.py::'
            'test_tracking_past_the_route_end_matches_the_views_to_the_last_snapshot',
        ),
        "the tracking window's last snapshot is left out: past the route's end the window is empty",
    ),
    Mutation(
        'chunk-crc-not-compared',
        'skynav_core/skynav_core/recording/mcapfile.py',
        'if len(records) != size or (crc and zlib.crc32(records) != crc):',
        'if len(records) != size:',
        ('skynav_core/test/test_mcapfile.py',),
        "a chunk's CRC is read but never compared: a damaged uncompressed chunk is not named",
    ),
    Mutation(
        'pair-tolerance-in-microseconds',
        'skynav_skyline/skynav_skyline/node.py',
        "int(values['pair_tolerance_ms'] * 1e6)",
        "int(values['pair_tolerance_ms'] * 1e3)",
        ('skynav_skyline/test/test_node.py::test_frames_of_one_exposure_pair_within_the_tolerance_of_their_stamps',),
        'pair_tolerance_ms read as microseconds: frames 0.5 ms apart no longer pair',
    ),
    Mutation(
        'camera-info-k1-k2-swapped',
        'skynav_core/skynav_core/camera.py',
        'k1, k2, k3, k4 = (float(x) for x in d)',
        'k2, k1, k3, k4 = (float(x) for x in d)',
        ('skynav_core/test/test_camera.py::test_a_distorted_camera_reads_back_from_its_camera_info',),
        'k1 and k2 swapped when a camera is read from CameraInfo',
    ),
    Mutation(
        'record-never-drains',
        'skynav_bringup/skynav_bringup/cli/record.py',
        """                executor.spin_once(timeout_sec=0.1)
            recorder.drain(executor)""",
        """                executor.spin_once(timeout_sec=0.1)""",
        ('test/test_replay_record.py::test_a_recorder_stopped_right_after_a_burst_keeps_all_of_it',),
        '`skynav record` finishes the file at Ctrl-C without taking what is still queued',
    ),
    Mutation(
        'compass-always-confident',
        'skynav_compass/skynav_compass/node.py',
        '                confident=bool(estimate.confident),',
        '                confident=True,',
        (
            'skynav_compass/test/test_node.py::test_map_reference_estimates_follow_the_ground_truth',
            'test/test_featureless_chain.py::test_the_node_graph_over_a_featureless_drive_with_its_own_map',
        ),
        'the compass node marks every estimate confident',
    ),
    Mutation(
        'compass-confidence-unpublished',
        'skynav_compass/skynav_compass/node.py',
        '                confidence=float(estimate.confidence),',
        '                confidence=0.0,',
        ('skynav_compass/test/test_node.py::test_map_reference_estimates_follow_the_ground_truth',),
        'the compass node publishes no confidence',
    ),
    Mutation(
        'warping-trusts-unconfident',
        'skynav_warping/skynav_warping/node.py',
        '            if compass is not None and not compass.confident:',
        '            if compass is not None and not compass.confident and compass.confidence < 0.0:',
        ('skynav_warping/test/test_node.py::test_only_a_confident_compass_rotation_starts_the_homing',),
        'the warping node starts its search from a compass rotation that is not confident',
    ),
    Mutation(
        'warping-not-counted',
        'skynav_warping/skynav_warping/node.py',
        '                self.compass_not_confident += 1\n',
        '                pass\n',
        ('skynav_warping/test/test_node.py::test_only_a_confident_compass_rotation_starts_the_homing',),
        'the warping node does not count the views aligned without their compass estimate',
    ),
    Mutation(
        'route-flag-dropped',
        'skynav_route/skynav_route/inputs.py',
        'bool(compass.confident), float(compass.confidence)',
        'True, float(compass.confidence)',
        (
            'skynav_route/test/test_inputs.py',
            'skynav_route/test/test_controller.py::test_a_wrong_compass_rotation_not_marked_confident_does_not_turn_the_robot',
        ),
        'the route node takes every compass rotation as confident',
    ),
    Mutation(
        'agreement-in-radians',
        'skynav_route/skynav_route/controller.py',
        '        bound = math.radians(COMPASS_AGREEMENT_DEG)',
        '        bound = COMPASS_AGREEMENT_DEG',
        (
            'skynav_route/test/test_controller.py::test_a_wrong_compass_rotation_not_marked_confident_does_not_turn_the_robot',
            'skynav_route/test/test_controller.py::test_a_compass_rotation_not_marked_confident_is_used_where_odometry_or_the_home_vector_agrees',
        ),
        'the agreement bound of a non-confident compass yaw in the wrong unit (20 rad: always agrees)',
    ),
    Mutation(
        'guess-confidence-uncapped',
        'skynav_route/skynav_route/controller.py',
        '            confidence = min(confidence, max(0.0, compass))',
        '            confidence = max(confidence, compass)',
        (
            'skynav_route/test/test_controller.py::test_a_compass_rotation_not_marked_confident_is_used_where_odometry_or_the_home_vector_agrees',
        ),
        "steering on a non-confident compass does not lower the feedback's confidence",
    ),
    Mutation(
        'predicted-heading-sign',
        'skynav_route/skynav_route/controller.py',
        '(self.heading + self._motion.command.angular * dt)',
        '(self.heading - self._motion.command.angular * dt)',
        (
            'skynav_route/test/test_controller.py::test_a_compass_rotation_not_marked_confident_is_used_where_odometry_or_the_home_vector_agrees',
            'skynav_route/test/test_controller.py::test_the_predicted_heading_follows_the_last_commands_turn',
        ),
        'the predicted heading turns against the last command',
    ),
    Mutation(
        'rival-gate-dropped',
        'skynav_compass/skynav_compass/compass.py',
        "            and details.get('rival_margin', 1.0) >= c.min_rival_margin\n",
        '',
        ('skynav_compass/test/test_compass.py',),
        'a rival rotation that fits the masks as well no longer keeps the estimate from being confident',
    ),
    Mutation(
        'rival-margin-of-a-duplicate',
        'skynav_compass/skynav_compass/compass.py',
        'rival = rival_margin(verified.disagreement[distinct])',
        'rival = rival_margin(verified.disagreement)',
        ('skynav_compass/test/test_compass.py',),
        'the rival margin taken against the next refined hypothesis, which may be the best one found twice',
    ),
    Mutation(
        'rival-tie-counts-as-no-rival',
        'skynav_compass/skynav_compass/compass.py',
        '    if disagreements[1] <= 0:\n        return 0.0',
        '    if disagreements[1] <= 0:\n        return 1.0',
        ('skynav_compass/test/test_compass.py',),
        'two hypotheses that both fit perfectly count as one without a rival',
    ),
    Mutation(
        'relative-distance-bound-ignored',
        'skynav_localize/skynav_localize/matching.py',
        '        return np.asarray(relative_distance) <= self.max_relative_distance',
        '        return np.ones(np.shape(relative_distance), bool)',
        ('skynav_localize/test/test_matching.py', 'skynav_localize/test/test_parallel_drive.py'),
        "a match's distance is no longer measured against the map's view change at its place",
    ),
    Mutation(
        'displaced-ratio-ignored',
        'skynav_localize/skynav_localize/matching.py',
        '            distinct = distinct & (np.asarray(displaced_ratio) <= self.max_displaced_ratio)',
        '            distinct = distinct',
        ('skynav_localize/test/test_matching.py',),
        'a place whose neighbours resemble places elsewhere still counts as distinct',
    ),
    Mutation(
        'exposure-over-whole-image',
        'skynav_skyline/skynav_skyline/exposure.py',
        '        int(np.count_nonzero(saturated & circle)) / inside,',
        '        int(np.count_nonzero(saturated)) / inside,',
        ('skynav_skyline/test/test_exposure.py',),
        'saturated pixels outside the image circle count towards overexposure',
    ),
    Mutation(
        'dark-frames-pass',
        'skynav_skyline/skynav_skyline/exposure.py',
        '    if dark > MAX_DARK_SHARE:',
        '    if dark > 1.0:',
        ('skynav_skyline/test/test_exposure.py', 'skynav_skyline/test/test_node.py'),
        'an underexposed frame is segmented by the dark-is-ground rule',
    ),
    Mutation(
        'opposite-step-not-checked',
        'skynav_warping/skynav_warping/warping3d.py',
        'confidence >= settings.confidence_threshold and best.ratio > 0 and opposite < settings.max_opposite_share',
        'confidence >= settings.confidence_threshold and best.ratio > 0',
        ('skynav_warping/test/test_warping3d.py',),
        'a home vector whose opposite step explains as much is still confident',
    ),
    Mutation(
        'undetermined-home-vector-published',
        'skynav_warping/skynav_warping/node.py',
        '            if not estimate.confident:\n',
        '            if False:\n',
        ('skynav_warping/test/test_node.py',),
        'the warping node publishes a home vector the views do not determine',
    ),
    Mutation(
        'refused-home-vector-is-missing',
        'skynav_route/skynav_route/controller.py',
        '        if view.home_direction is None and view.home_expected and self._refusal_credible(view):',
        '        if view.home_direction is None and not view.home_expected and self._refusal_credible(view):',
        ('skynav_route/test/test_controller.py', 'skynav_route/test/test_node.py'),
        'the Homer takes a refused home vector as a missing one (LOST near home) and a missing one as arrived',
    ),
    Mutation(
        'refusal-always-credible',
        'skynav_route/skynav_route/controller.py',
        '        return self.heard or near',
        '        return True',
        ('skynav_route/test/test_controller.py', 'skynav_route/test/test_node.py'),
        'a Homer that never heard a home vector arrives on silence wherever the robot stands',
    ),
    Mutation(
        'confident-share-over-all',
        'skynav_compass/skynav_compass/eval/evaluation.py',
        '    return ConfidentStatistics(float(flags.mean()), int(flags.sum()),',
        '    return ConfidentStatistics(float(np.mean(confident)), int(flags.sum()),',
        ('skynav_compass/test/test_evaluation.py',),
        'the confident share of a group counted over every estimate',
    ),
    Mutation(
        'confident-median-over-all',
        'skynav_compass/skynav_compass/eval/evaluation.py',
        'float(np.median(e[flags])), float(e[flags].max()))',
        'float(np.median(e)), float(e[flags].max()))',
        ('skynav_compass/test/test_evaluation.py',),
        'the median error of the confident estimates taken over all of them',
    ),
    Mutation(
        'failed-estimate-no-error',
        'skynav_compass/skynav_compass/eval/evaluation.py',
        '    e = np.where(np.isfinite(errors), errors, 180.0)[chosen]',
        '    e = np.where(np.isfinite(errors), errors, 0.0)[chosen]',
        ('skynav_compass/test/test_evaluation.py',),
        'a failed estimate counts as no error among the confident',
    ),
)


def dirty(paths: list[str]) -> list[str]:
    """Return those of the paths (relative to the root) that differ from git's HEAD."""
    result = subprocess.run(
        ['git', 'status', '--porcelain', '--', *paths], cwd=ROOT, capture_output=True, text=True, check=True
    )
    return [line[3:] for line in result.stdout.splitlines()]


def failed_tests(output: str) -> list[str]:
    """Return the node ids pytest's short summary lists as failed or in error."""
    return sorted({m.group(2) for m in re.finditer(r'^(FAILED|ERROR) (\S+)', output, re.MULTILINE)})


def run_tests(tests: tuple[str, ...], timeout: float) -> tuple[int, str]:
    """Run pytest on the tests (quietly, in a subprocess); return its exit code and output."""
    environment = dict(os.environ, PYTHONDONTWRITEBYTECODE='1')
    command = [sys.executable, '-m', 'pytest', '-q', '-p', 'no:cacheprovider', '-rfE', '--no-header', *tests]
    try:
        result = subprocess.run(command, cwd=ROOT, env=environment, capture_output=True, text=True, timeout=timeout)
    except subprocess.TimeoutExpired:
        return -1, 'timed out'
    return result.returncode, result.stdout + result.stderr


def apply_and_test(mutation: Mutation, timeout: float) -> tuple[bool, list[str], float, str]:
    """Patch the file, run the tests, restore the file; return (killed, failed tests, seconds, pytest's last line)."""
    path = ROOT / mutation.path
    original = path.read_bytes()
    status = path.stat()
    text = original.decode()
    if text.count(mutation.old) != 1:
        raise SystemExit(
            f'{mutation.name}: the patch must occur exactly once in {mutation.path} (found {text.count(mutation.old)})'
        )
    start = time.monotonic()
    try:
        path.write_text(text.replace(mutation.old, mutation.new))
        code, output = run_tests(mutation.tests, timeout)
    finally:
        path.write_bytes(original)
        os.utime(path, ns=(status.st_atime_ns, status.st_mtime_ns))
    lines = output.strip().splitlines()
    # pytest exits 1 when tests failed; 2-5 (interrupted, internal error, usage, no tests) prove nothing
    return code == 1, failed_tests(output), time.monotonic() - start, lines[-1] if lines else ''


def main() -> int:
    """Run the chosen mutations (default: all) and print the table; exit 1 if any mutation survives."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('names', nargs='*', help='mutations to run (default: all)')
    parser.add_argument('--list', action='store_true', help='list the mutations and their tests, run nothing')
    parser.add_argument('--timeout', type=float, default=900.0, help='seconds per mutation (default 900)')
    parser.add_argument(
        '--no-baseline', action='store_true', help='skip the first run of the tests without a mutation (must pass)'
    )
    args = parser.parse_args()
    known = {m.name: m for m in MUTATIONS}
    if unknown := [n for n in args.names if n not in known]:
        parser.error(f'unknown mutation(s) {", ".join(unknown)}; known: {", ".join(known)}')
    chosen = [known[n] for n in args.names] if args.names else list(MUTATIONS)
    if args.list:
        for m in chosen:
            print(f'{m.name}: {m.what}\n    {m.path}\n    tests: {" ".join(m.tests)}')
        return 0
    if changed := dirty(sorted({m.path for m in chosen})):
        print(f'mutants: commit your changes to {", ".join(changed)} first', file=sys.stderr)
        return 1
    signal.signal(signal.SIGTERM, signal.default_int_handler)  # SIGTERM unwinds like Ctrl-C: files are restored
    if not args.no_baseline:  # a failure counts as a kill only if the same tests pass without the mutation
        tests = tuple(dict.fromkeys(test for m in chosen for test in m.tests))
        code, output = run_tests(tests, args.timeout)
        if code != 0:
            print(f'mutants: the tests fail without any mutation: {", ".join(failed_tests(output))}', file=sys.stderr)
            return 1
    rows = []
    for m in chosen:
        killed, failed, seconds, last = apply_and_test(m, args.timeout)
        rows.append((m.name, killed, failed, seconds))
        print(f'{m.name}: {"killed" if killed else "SURVIVED"} in {seconds:.0f} s ({last})', file=sys.stderr)
    width = max(len(r[0]) for r in rows)
    print(f'{"mutation":<{width}}  killed  seconds  failed tests')
    for name, killed, failed, seconds in rows:
        shown = [test.rsplit('/', 1)[-1] for test in failed[:SHOWN_TESTS]]
        more = f' (+{len(failed) - SHOWN_TESTS} more)' if len(failed) > SHOWN_TESTS else ''
        print(f'{name:<{width}}  {"yes" if killed else "NO":<6}  {seconds:7.0f}  {", ".join(shown) or "-"}{more}')
    survivors = sum(not r[1] for r in rows)
    print(f'{len(rows) - survivors} of {len(rows)} mutations killed')
    return 1 if survivors else 0


if __name__ == '__main__':
    sys.exit(main())
