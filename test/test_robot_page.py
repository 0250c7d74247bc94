# SPDX-License-Identifier: Apache-2.0
"""docs/robot.md, from a bare robot to a taught and repeated route: its commands run as the page gives them.

The page marks the code blocks that need no robot with an HTML comment on the line before the block:

- `<!-- test: runs -->`: the block's commands run (bash, stopping at the first that fails) and exit 0;
  `<!-- test: runs, exit N -->`: the block shows an error the user should recognise: it exits N, with one line of
  error and no traceback;
- `<!-- test: starts -->`: the block's one command keeps running (a terminal of its own: `skynav launch`,
  `record`, ...); `, ready at "TEXT"`: the next block waits until its output says TEXT; `, ends by itself`: it
  finishes on its own (a replay);
- `<!-- test: Ctrl-C -->` (not before a block): the started commands that end by themselves are waited for, then
  the others get Ctrl-C (SIGINT), newest first; each must exit 0;
- `<!-- test: file NAME -->`: the block is a file the following commands use (a parameter file).

Blocks without a marker need the robot. Every `skynav` command line of every block, those too, must parse as the
installed `skynav` parses it (a page naming an option or a value that does not exist fails), the options of every
inline `skynav ...` span must exist, `ros2 launch` lines may name only the launch file's declared arguments, and
the page's links must lead to files and headings that exist.

The runnable blocks run in page order in one temporary folder whose `bags/` holds the repository's bundled
synthetic recordings, with `synthetic_garden_repeat.mcap` cut to its first exposures
(skynav_testing.write_first_frames) so that `skynav run` over it stays short; `skynav` is this virtualenv's
(its folder first on PATH), on the test run's own ROS domain (conftest.py).
"""

from __future__ import annotations

import contextlib
import io
import os
import re
import shlex
import signal
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import pytest

from skynav_testing import one_line_error, write_first_frames

pytestmark = pytest.mark.heavy(135)

ROOT = Path(__file__).parents[1]
PAGE = ROOT / 'docs' / 'robot.md'
BAGS = ROOT / 'bags'
LAUNCH_FILE = ROOT / 'skynav_bringup' / 'launch' / 'skynav.launch.py'
CUT_BAG, CUT_FRAMES = 'synthetic_garden_repeat.mcap', 20
SHELLS = ('bash', 'sh', 'console')
# what the page's runnable blocks must cover: the commands the issue asks the page to run without a robot
RUN_COVERS = {'bench', 'sim boards', 'calibrate', 'map build', 'run', 'info', 'map info', 'launch', 'record', 'teach'}
RUN_COVERS |= {'replay', 'echo'}
SAFETY_TIMEOUT = 300  # s: a net against a hang, never a measure of speed

MARKER = re.compile(r'^<!--\s*test:\s*(?P<spec>.*?)\s*-->\s*$')
FENCE = re.compile(r'^```(?P<lang>[\w-]*)\s*$')


@dataclass
class Step:
    """One marked part of the page: what the test does with it, in page order."""

    kind: str  # runs, starts, file, ctrl-c
    line: int  # 1-based line of the marker
    body: str = ''
    exit_code: int = 0
    ready_at: str | None = None
    ends_by_itself: bool = False
    name: str = ''  # file name


def blocks(text: str) -> list[tuple[int, str, str, str | None]]:
    """Return the page's fenced blocks: (line of the fence, language, body, marker spec on the line before)."""
    lines, found, i = text.splitlines(), [], 0
    while i < len(lines):
        fence = FENCE.match(lines[i])
        if not fence:
            i += 1
            continue
        end = next(j for j in range(i + 1, len(lines)) if lines[j].startswith('```'))
        marker = MARKER.match(lines[i - 1]) if i else None
        found.append((i + 1, fence['lang'], '\n'.join(lines[i + 1 : end]), marker['spec'] if marker else None))
        i = end + 1
    return found


def parse_spec(spec: str, line: int) -> Step:
    """Return the step a marker's text names; ValueError for one the test does not understand."""
    words = [part.strip() for part in spec.split(',')]
    head, options = words[0], words[1:]
    if head == 'Ctrl-C' and not options:
        return Step('ctrl-c', line)
    if head.startswith('file '):
        return Step('file', line, name=head.removeprefix('file ').strip())
    if head == 'runs' and all(re.fullmatch(r'exit \d+', option) for option in options) and len(options) <= 1:
        return Step('runs', line, exit_code=int(options[0].split()[1]) if options else 0)
    if head == 'starts':
        step = Step('starts', line)
        for option in options:
            ready = re.fullmatch(r'ready at "(.+)"', option)
            if ready:
                step.ready_at = ready[1]
            elif option == 'ends by itself':
                step.ends_by_itself = True
            else:
                raise ValueError(f'docs/robot.md:{line}: unknown option {option!r} of a test marker')
        return step
    raise ValueError(f'docs/robot.md:{line}: a test marker the test does not understand: {spec!r}')


def steps(text: str) -> list[Step]:
    """Return the page's marked steps in order; ValueError for a marker that is misplaced or not understood."""
    marked = {}  # marker line -> step
    for fence_line, lang, body, spec in blocks(text):
        if spec is None:
            continue
        step = parse_spec(spec, fence_line - 1)
        if step.kind == 'ctrl-c':
            raise ValueError(f'docs/robot.md:{step.line}: a Ctrl-C marker stands alone, not before a block')
        if step.kind != 'file' and lang not in SHELLS:
            raise ValueError(f'docs/robot.md:{step.line}: a runnable block must be bash, not {lang!r}')
        if step.kind == 'starts' and len(command_lines(body)) != 1:
            raise ValueError(f'docs/robot.md:{step.line}: a started block holds exactly one command')
        step.body = body
        marked[step.line] = step
    lines = text.splitlines()
    for number, line in enumerate(lines, 1):
        marker = MARKER.match(line)
        if marker and number not in marked:
            step = parse_spec(marker['spec'], number)
            if step.kind != 'ctrl-c':
                raise ValueError(f'docs/robot.md:{number}: a test marker must stand on the line before a block')
            marked[number] = step
    return [marked[number] for number in sorted(marked)]


def command_lines(body: str) -> list[str]:
    """Return the commands of a shell block: continued lines joined, comments left out, split at ;, &&, || and |."""
    text = re.sub(r'\\\n\s*', ' ', body)
    commands = []
    for line in text.splitlines():
        line = line.strip().removeprefix('$ ')
        if not line or line.startswith('#'):
            continue
        for part in re.split(r'\s*(?:&&|\|\||;|\|)\s*', line):
            part = re.sub(r'\s+#.*$', '', part).rstrip('&').strip()
            if part:
                commands.append(part)
    return commands


def skynav_lines(text: str) -> list[list[str]]:
    """Return the arguments of every `skynav` command in the page's shell blocks (marked or not)."""
    found = []
    for _, lang, body, _ in blocks(text):
        if lang in SHELLS:
            found += [shlex.split(c)[1:] for c in command_lines(body) if c.split()[0] in ('skynav', '.venv/bin/skynav')]
    return found


def prose(text: str) -> str:
    """Return the page without its fenced blocks."""
    return re.sub(r'^```.*?^```', '', text, flags=re.M | re.S)


def command_parser(words: list[str]):
    """Return the parser of the skynav (sub)command that `words` name and how many words named it."""
    import argparse

    from skynav_bringup.cli import build_parser

    parser, used = build_parser(words), 0
    for word in words:
        sub = next((a for a in parser._actions if isinstance(a, argparse._SubParsersAction)), None)
        if sub is None or word not in sub.choices:
            break
        parser, used = sub.choices[word], used + 1
    return parser, used


def unknown_options(words: list[str]) -> list[str]:
    """Return the options of `skynav WORDS` that its command does not have by that exact name (argparse would take a
    prefix of a longer one)."""
    parser, used = command_parser(words)
    options = {o for action in parser._actions for o in action.option_strings}
    return [w for w in words[used:] if w.startswith('--') and w.split('=')[0] not in options]


def parse(words: list[str]) -> str:
    """Return what `skynav WORDS` says when its arguments do not parse ('' when they do)."""
    from skynav_bringup.cli import build_parser

    errors = io.StringIO()
    with contextlib.redirect_stderr(errors), contextlib.redirect_stdout(io.StringIO()):
        try:
            build_parser(words).parse_args(words)
        except SystemExit as stop:
            if stop.code:
                return errors.getvalue().strip() or f'exit {stop.code}'
    return ''


def test_the_markers_are_understood_and_the_page_runs_what_it_must():
    page = PAGE.read_text()
    marked = steps(page)
    covered = {
        ' '.join(command_parser(shlex.split(line)[1:])[0].prog.split()[1:])
        for step in marked
        if step.kind in ('runs', 'starts')
        for line in command_lines(step.body)
        if line.startswith('skynav ')
    }
    assert RUN_COVERS <= covered, f'the page no longer runs {sorted(RUN_COVERS - covered)}'
    started = 0
    for step in marked:  # every command the page starts is stopped again
        started = started + 1 if step.kind == 'starts' else 0 if step.kind == 'ctrl-c' else started
    assert started == 0, 'a command the page starts is never stopped by a Ctrl-C marker'
    # a misplaced or misspelled marker is refused rather than silently skipped
    with pytest.raises(ValueError, match='does not understand'):
        steps('<!-- test: run -->\n```bash\nskynav info x.mcap\n```\n')
    with pytest.raises(ValueError, match='line before a block'):
        steps('<!-- test: runs -->\n\n```bash\nskynav info x.mcap\n```\n')


def test_every_skynav_command_of_the_page_parses():
    commands = skynav_lines(PAGE.read_text())
    assert len(commands) >= 20  # the page's commands were found
    failures = [f'skynav {shlex.join(words)}: {error}' for words in commands if (error := parse(words))]
    failures += [
        f'skynav {shlex.join(words)}: no option {unknown_options(words)}'
        for words in commands
        if unknown_options(words)
    ]
    assert not failures, '\n'.join(failures)
    # the check sees a wrong option, a wrong value and a missing argument
    assert 'unrecognized arguments: --namespaces' in parse(['launch', '--namespaces', 'robot1'])
    assert parse(['follow', 'garden.db', '--from', 'start'])
    assert parse(['home', 'garden.db'])
    assert unknown_options(['launch', '--name', 'robot1']) == ['--name']  # a prefix argparse would take


def test_the_options_named_in_the_text_exist():
    spans = re.findall(r'`(skynav [^`]*)`', prose(PAGE.read_text()))
    assert len(spans) >= 10
    failures = [
        f'`{span}`: {unknown_options(shlex.split(span)[1:])}'
        for span in spans
        if unknown_options(shlex.split(span)[1:])
    ]
    assert not failures, 'options the commands do not have:\n' + '\n'.join(failures)


def test_the_launch_file_declares_the_arguments_the_page_names():
    declared = set(re.findall(r"DeclareLaunchArgument\(\s*'(\w+)'", LAUNCH_FILE.read_text()))
    assert {'namespace', 'map', 'params_file', 'use_sim_time', 'camera'} <= declared
    named = set()
    for _, lang, body, _ in blocks(PAGE.read_text()):
        for command in command_lines(body) if lang in SHELLS else []:
            if command.startswith('ros2 launch skynav_bringup skynav.launch.py'):
                named |= {word.split(':=')[0] for word in shlex.split(command)[4:]}
    assert named, 'the page shows no ros2 launch line'
    assert named <= declared, f'the launch file declares no {sorted(named - declared)}'


def test_the_commands_that_need_no_robot_run_as_the_page_gives_them(tmp_path):
    bags = tmp_path / 'bags'
    bags.mkdir()
    for bag in BAGS.glob('*.mcap'):
        if bag.name != CUT_BAG:
            (bags / bag.name).symlink_to(bag)
    write_first_frames(BAGS / CUT_BAG, bags / CUT_BAG, CUT_FRAMES)
    env = {**os.environ, 'PATH': f'{Path(sys.executable).parent}{os.pathsep}{os.environ.get("PATH", "")}'}
    assert Path(sys.executable).with_name('skynav').exists()

    started: list[tuple[Step, subprocess.Popen, Path]] = []

    def written(log: Path) -> str:
        return log.read_text(errors='replace') if log.exists() else ''

    def stop_all() -> list[str]:
        """Wait for the started commands that end by themselves, Ctrl-C the others, newest first; their failures."""
        failures = []
        while started:
            step, process, log = started.pop()
            try:
                if not step.ends_by_itself:
                    process.send_signal(signal.SIGINT)
                process.wait(timeout=SAFETY_TIMEOUT)
            except subprocess.TimeoutExpired:
                process.kill()
                process.wait()
            if process.returncode != 0:
                failures.append(f'docs/robot.md:{step.line}: {step.body!r} exit {process.returncode}\n{written(log)}')
        return failures

    try:
        for number, step in enumerate(steps(PAGE.read_text())):
            where = f'docs/robot.md:{step.line}'
            if step.kind == 'file':
                (tmp_path / step.name).write_text(step.body + '\n')
            elif step.kind == 'runs':
                done = subprocess.run(
                    ['bash', '-e', '-o', 'pipefail', '-c', step.body],
                    cwd=tmp_path,
                    env=env,
                    capture_output=True,
                    text=True,
                    timeout=SAFETY_TIMEOUT,
                )
                said = f'{where}: {step.body!r}\n{done.stdout[-3000:]}{done.stderr[-3000:]}'
                assert done.returncode == step.exit_code, f'exit {done.returncode}, not {step.exit_code}: {said}'
                if step.exit_code:
                    assert one_line_error(done.stderr), said
            elif step.kind == 'starts':
                log = tmp_path / f'started_{number}.log'
                with open(log, 'w') as out:
                    process = subprocess.Popen(
                        ['bash', '-c', f'exec {command_lines(step.body)[0]}'],
                        cwd=tmp_path,
                        env=env,
                        stdout=out,
                        stderr=subprocess.STDOUT,
                    )
                started.append((step, process, log))
                deadline = time.monotonic() + SAFETY_TIMEOUT
                while step.ready_at and step.ready_at not in written(log):
                    if process.poll() is not None:
                        pytest.fail(f'{where}: ended (exit {process.returncode}) before it was ready:\n' + written(log))
                    assert time.monotonic() < deadline, f'{where}: never said {step.ready_at!r}:\n' + written(log)
                    time.sleep(0.1)
            else:  # Ctrl-C
                failures = stop_all()
                assert not failures, '\n'.join(failures)
    finally:
        stop_all()


def slug(heading: str) -> str:
    """Return the anchor GitHub gives a Markdown heading."""
    return re.sub(r'[^\w\- ]', '', heading.strip().lower()).replace(' ', '-')


def test_the_links_lead_to_files_and_headings_that_exist():
    links = re.findall(r'\]\(([^)\s]+)\)', prose(PAGE.read_text()))
    assert len(links) >= 10
    failures = []
    for link in links:
        if re.match(r'\w+://', link):
            continue
        path, _, anchor = link.partition('#')
        target = (PAGE.parent / path).resolve() if path else PAGE
        if not target.is_file():
            failures.append(f'{link}: no file {target}')
        elif anchor and anchor not in {slug(h) for h in re.findall(r'^#+ (.+)$', prose(target.read_text()), re.M)}:
            failures.append(f'{link}: no heading #{anchor} in {path or PAGE.name}')
    assert not failures, '\n'.join(failures)
    assert slug('Driving: teach, follow, home') == 'driving-teach-follow-home'
    assert slug('The `skynav` command') == 'the-skynav-command'
