# SPDX-License-Identifier: Apache-2.0
"""Publish a recording's messages on their topics with their recorded timing.

The stored CDR bytes are published unchanged. Publishers offer RELIABLE (and
TRANSIENT_LOCAL where the recording's publishers were latched), which every
subscriber can match. BAG is a rosbag2 directory or a bare .mcap file.

Before the first message it waits until every replayed topic has its subscribers
(by default: the nodes of the skynav graph that read it), so that a graph
started just before loses no message to discovery; it says at once what it waits
for, and every few seconds what is still missing. It then shows its progress (a
bar on a terminal, a line every PROGRESS_PERIOD s elsewhere). With --namespace NS
each recorded topic is published under /NS (/NS/camera/uv/image_raw, the
recording's /clock as /NS/clock) for a graph launched there. After the last one it waits
until reliable subscribers acknowledged everything (at most 5 s) and gives
best-effort ones 1 s to take the last messages before its publishers go.
"""

from __future__ import annotations

import argparse
import sys
import time

from skynav_core.cli import add_namespace, add_skip_damaged

HELP = 'publish a bag on its topics with the recorded timing'
PROGRESS_PERIOD = 10.0  # s between progress lines when stderr is not a terminal


def configure(parser: argparse.ArgumentParser) -> None:
    """Add the arguments of `skynav replay`."""
    parser.add_argument('bag', metavar='BAG', help='rosbag2 directory or .mcap file')
    add_skip_damaged(parser)
    parser.add_argument(
        '--rate',
        type=float,
        default=1.0,
        metavar='R',
        help='speed factor of the recorded timing; 0 publishes as fast as possible (default 1)',
    )
    parser.add_argument('--loop', action='store_true', help='start again at the end, until Ctrl-C')
    parser.add_argument('--topics', nargs='+', metavar='TOPIC', help='replay only these topics')
    parser.add_argument(
        '--wait-for-subscribers',
        type=int,
        metavar='N',
        help='before the first message, wait until every replayed topic has N subscribers (0: do not wait); '
        "default: until each topic's readers in the skynav graph (every installed node that subscribes to it) "
        'have all matched',
    )
    parser.add_argument(
        '--wait-timeout',
        type=float,
        default=30.0,
        metavar='SECONDS',
        help='wait for subscribers at most this long, then publish anyway with a warning (default 30)',
    )
    add_namespace(parser, 'the graph to feed: each recorded topic is published under /NS')


def run(args: argparse.Namespace) -> int:
    """Replay the bag; return the exit code."""
    from skynav_core.recording.bag import open_bag
    from skynav_core.ros import StopRequest, tool_node

    from . import CliError

    if args.rate < 0:
        raise CliError('--rate must be 0 (as fast as possible) or positive', exit_code=2)
    if (args.wait_for_subscribers or 0) < 0 or args.wait_timeout < 0:
        raise CliError('--wait-for-subscribers and --wait-timeout must not be negative', exit_code=2)
    where = f' under {args.namespace}' if args.namespace else ''
    with open_bag(args.bag) as bag:  # a damaged bag is refused in one line before anything else is said
        topics = args.topics or list(bag.topics)
        if missing := [t for t in topics if t not in bag.topics]:
            raise CliError(f'{args.bag} has no topic {", ".join(missing)} (it has {", ".join(bag.topics)})')
        count, duration = sum(bag.topics[t].count for t in topics), (bag.end_time - bag.start_time) / 1e9
        if args.wait_for_subscribers == 0:
            say(f'{count} messages on {len(topics)} topics{where}, {duration:.1f} s: publishing at once')
        else:
            readers = (
                f'{args.wait_for_subscribers} subscribers on each topic'
                if args.wait_for_subscribers
                else f"the skynav graph's nodes{where} that read them"
            )
            say(
                f'{count} messages on {len(topics)} topics{where}, {duration:.1f} s; first waiting up to '
                f'{args.wait_timeout:g} s for {readers} (--wait-for-subscribers 0: do not wait)'
            )
        expected = _expected_subscribers(topics, args.wait_for_subscribers)
        if names := _readers(expected):
            say(f'waiting for {names}')
        from skynav_core.recording.player import SUBSCRIBER_LINGER, Player

        with StopRequest() as stop, tool_node('skynav_replay') as (node, executor):
            player = Player(node, bag, topics, args.namespace)
            if any(expected.values()):
                lonely = player.wait_for_subscribers(
                    executor,
                    expected,
                    args.wait_timeout,
                    stop,
                    report=lambda short, waited: say(f'{waited:.0f} s: still waiting on {"; ".join(short)}'),
                )
                if lonely and not stop.requested:
                    print(
                        f'skynav replay: after {args.wait_timeout:g} s still waiting on {"; ".join(lonely)}; '
                        'publishing anyway (--wait-for-subscribers 0: do not wait)',
                        file=sys.stderr,
                    )
            stats = _play_with_progress(player, args, stop)
    print(
        f'skynav replay: published {stats.total} messages on {len(stats.published)} topics '
        f'in {stats.wall_time:.2f} s ({stats.total / max(stats.wall_time, 1e-9):.1f} msg/s)'
        + (f', {stats.loops} passes' if args.loop else '')
        + (' (interrupted)' if stop.requested else '')
        + (
            f'; gave {stats.best_effort} best-effort subscribers {SUBSCRIBER_LINGER:g} s to take the last messages'
            if stats.best_effort
            else ''
        ),
        file=sys.stderr,
    )
    if stats.unacknowledged:
        print(
            f'skynav replay: warning: not every subscriber acknowledged {", ".join(stats.unacknowledged)}',
            file=sys.stderr,
        )
    return 0


def say(text: str) -> None:
    """Print one line of the command's own."""
    print(f'skynav replay: {text}', file=sys.stderr, flush=True)


def _readers(expected: dict) -> str:
    """Return the graph's nodes a replay waits for, by name ('' when it waits for none, or for a number)."""
    return ', '.join(sorted({name for want in expected.values() if not isinstance(want, int) for name in want}))


def _expected_subscribers(topics: list[str], count: int | None) -> dict:
    """Return per topic the subscribers to wait for: `count` of them, or by default the skynav graph's readers."""
    if count is not None:
        return {topic: count for topic in topics}
    from skynav_core.graph import graph_readers
    from skynav_core.nodes import installed_nodes

    readers = graph_readers(installed_nodes())
    return {topic: readers.get(topic, []) for topic in topics}


def _play_with_progress(player, args: argparse.Namespace, stop):
    """Play with a progress bar on an interactive terminal, a line every PROGRESS_PERIOD s elsewhere."""
    from tqdm import tqdm

    bag = player.bag
    duration = (bag.end_time - bag.start_time) / 1e9
    tty = sys.stderr.isatty()
    printed_at = time.monotonic()
    published = 0
    with tqdm(
        total=None if args.loop else player.message_count,
        unit='msg',
        desc='replay',
        file=sys.stderr,
        disable=not tty,
        dynamic_ncols=True,
    ) as bar:

        def advance(message) -> None:
            nonlocal printed_at, published
            at = f'{(message.log_time - bag.start_time) / 1e9:6.2f}/{duration:.2f} s'
            bar.update(1)
            bar.set_postfix_str(at, refresh=False)
            published += 1
            if not tty and time.monotonic() - printed_at >= PROGRESS_PERIOD:
                printed_at = time.monotonic()
                say(f'{published} messages published, at {at.strip()} of the recording')

        return player.play(args.rate, args.loop, stop, on_message=advance)
