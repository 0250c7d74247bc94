# SPDX-License-Identifier: Apache-2.0
"""The `skynav` command line: help everywhere, exit codes users expect, no tracebacks for bad input."""

import pytest

from skynav_bringup.cli import build_parser, main
from skynav_testing import one_line_error, run_skynav, write_sample_bag


def _commands(parser, path=()):
    """Yield the path of every (sub)command of a parser."""
    for action in parser._actions:
        if action.__class__.__name__ == '_SubParsersAction':
            for name, sub in action.choices.items():
                yield (*path, name)
                yield from _commands(sub, (*path, name))


def test_every_command_has_help(capsys):
    commands = list(_commands(build_parser()))
    assert {('replay',), ('record',), ('echo',), ('info',), ('launch',)} <= set(commands)
    result = run_skynav('--help')  # the command itself, once; its subcommands' help in this process (as fast)
    assert result.returncode == 0 and 'usage: skynav' in result.stdout, result.stderr
    for command in commands:
        with pytest.raises(SystemExit) as exited:
            main([*command, '--help'])
        assert exited.value.code == 0, command
        assert f'usage: skynav {" ".join(command)}' in capsys.readouterr().out, command


def test_usage_errors_exit_2():
    assert run_skynav().returncode == 2
    assert run_skynav('no-such-command').returncode == 2
    assert run_skynav('replay').returncode == 2
    result = run_skynav('replay', 'x.mcap', '--rate', '-1')
    assert result.returncode == 2 and one_line_error(result.stderr)
    result = run_skynav('record', 'out.mcap')
    assert result.returncode == 2 and one_line_error(result.stderr)


def test_info_describes_a_bag(tmp_path):
    write_sample_bag(tmp_path / 'b.mcap', frames=3)
    result = run_skynav('info', str(tmp_path / 'b.mcap'))
    assert result.returncode == 0, result.stderr
    assert 'Messages:          24' in result.stdout
    assert 'Duration:          0.200000000s' in result.stdout
    for line in ('Topic: /skyline/sh', 'Type: skynav_msgs/msg/ShCoefficients', 'Count: 3'):
        assert line in result.stdout


@pytest.mark.parametrize(
    'args',
    [
        ('info', 'missing.mcap'),
        ('replay', 'missing.mcap'),
        ('echo', '/x', '--type', 'no_pkg/msg/Nothing'),
        ('launch', '--params', 'missing.yaml'),
    ],
)
def test_bad_input_is_one_line_and_exit_1(tmp_path, args):
    result = run_skynav(*args, cwd=tmp_path)
    assert result.returncode == 1
    assert one_line_error(result.stderr), result.stderr


def test_params_file_must_be_ros_yaml(tmp_path):
    bad = tmp_path / 'p.yaml'
    bad.write_text('skyline: {threshold: 1}\n')
    result = run_skynav('launch', '--params', str(bad))
    assert result.returncode == 1 and 'not in the ROS 2 format' in result.stderr
    bad.write_text('a: [1, 2\n')
    result = run_skynav('launch', '--params', str(bad))
    assert result.returncode == 1 and one_line_error(result.stderr)
    # ROS refuses a list that mixes integers and floats (rcl: "Sequence should be of same type"), in every node
    bad.write_text('/**:\n  ros__parameters:\n    camera_mount_rpy_deg: [0, 0.0, 90.0]\n')
    for command in (['launch'], ['run', 'missing.mcap', '--out', str(tmp_path / 'out.mcap')]):
        result = run_skynav(*command, '--params', str(bad))
        assert result.returncode == 1 and one_line_error(result.stderr), result.stderr
        assert 'camera_mount_rpy_deg' in result.stderr and '[0.0, 0.0, 90.0]' in result.stderr


def test_a_package_found_twice_on_the_path_gives_its_commands_once(monkeypatch):
    # an overlay workspace over an underlay lists a package's entry points twice: the first on the path wins
    import skynav_bringup.cli as cli

    listed = list(cli.entry_points(group=cli.COMMAND_GROUP))
    follow = next(ep for ep in listed if ep.name == 'follow')
    shadowed = type(follow)('follow', 'skynav_bringup.cli.info', cli.COMMAND_GROUP)  # a later copy, another module
    monkeypatch.setattr(cli, 'entry_points', lambda group: [*listed, shadowed])
    parser = build_parser(['follow', '--help'])
    choices = next(a for a in parser._actions if a.__class__.__name__ == '_SubParsersAction').choices
    assert choices['follow'].get_default('run').__module__ == follow.value
