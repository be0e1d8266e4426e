"""The client's argument parsing and validation (tiago_nav.mission.client): nothing is sent
unless every value is a finite number and the yaw is in degrees; missing values are asked for
only in a terminal."""
import os
import subprocess
import sys

import pytest

from tiago_nav.mission.client import (EXIT_USAGE, UsageError, feedback_line, parse_client_args)

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def test_parses_pose_b_and_the_corridor_flag():
    g = parse_client_args(['11', '0', '-45'])
    assert (g['x'], g['y'], g['yaw_deg'], g['use_corridor_law']) == (11.0, 0.0, -45.0, True)
    g = parse_client_args(['--no-corridor', '1.5', '-2', '90', '--server-timeout=3'])
    assert (g['x'], g['y'], g['yaw_deg'], g['use_corridor_law']) == (1.5, -2.0, 90.0, False)
    assert g['server_timeout'] == 3.0
    assert parse_client_args(['-h']) == {'help': True}
    assert parse_client_args(['1', '2', '3', '--corridor=false'])['use_corridor_law'] is False
    assert parse_client_args(['1', '2', '3', '--corridor=True'])['use_corridor_law'] is True


@pytest.mark.parametrize('argv, words', [
    (['a', '0', '0'], "'a' is not a number"),
    (['1', 'nan', '0'], 'not a finite number'),
    (['1', '0', 'inf'], 'not a finite number'),
    (['1', '0', '1000'], 'in degrees'),
    (['1', '0'], 'missing YAW_DEG'),
    ([], 'missing X, Y, YAW_DEG'),
    (['1', '2', '3', '4'], 'too many'),
    (['1', '2', '3', '--fast'], 'unknown option --fast'),
    (['1', '2', '3', '--corridor=maybe'], 'expected true or false'),
    (['1', '2', '3', '--server-timeout', '-1'], 'must be > 0'),
])
def test_bad_input_is_a_usage_error(argv, words):
    with pytest.raises(UsageError) as e:
        parse_client_args(argv, interactive=False)
    assert words in str(e.value)


def test_prompts_for_missing_values_in_a_terminal():
    answers = iter(['0.5', '-30'])
    asked = []

    def ask(prompt):
        asked.append(prompt)
        return next(answers)
    g = parse_client_args(['2'], interactive=True, ask=ask)
    assert (g['x'], g['y'], g['yaw_deg']) == (2.0, 0.5, -30.0)
    assert asked == ['y [m]: ', 'yaw [deg]: ']
    with pytest.raises(UsageError):
        parse_client_args(['2'], interactive=True, ask=lambda p: 'north')


def test_feedback_line():
    line = feedback_line(12.5, 3, 'moving, 3.2 m to go', (1.0, 2.0, 0.0))
    assert 'MOVING' in line and 'moving, 3.2 m to go' in line and '(1.00, 2.00, 0 deg)' in line


@pytest.mark.ros                 # the node module imports rospy
@pytest.mark.parametrize('argv', [['x', '0', '0'], ['1', '2'], ['1', '2', '-400']])
def test_the_node_exits_2_without_a_master(argv):
    """Bad input is refused before rospy is even initialised: no master needed, nothing sent."""
    env = dict(os.environ, ROS_MASTER_URI='http://localhost:1')     # nothing listens there
    env['PYTHONPATH'] = os.path.join(ROOT, 'src') + os.pathsep + env.get('PYTHONPATH', '')
    p = subprocess.run([sys.executable, os.path.join(ROOT, 'nodes', 'client')] + argv,
                       stdin=subprocess.DEVNULL, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                       text=True, env=env, timeout=60)
    assert p.returncode == EXIT_USAGE, p.stderr
    assert 'client: error:' in p.stderr and 'usage:' in p.stderr


def test_numbers_that_look_like_options_stay_values():
    """argparse takes a leading '-' for an option: negative numbers, -inf and -nan must still
    be read (and judged) as values, and a bare --corridor must not swallow X."""
    g = parse_client_args(['-1.5', '-2', '-45'])
    assert (g['x'], g['y'], g['yaw_deg']) == (-1.5, -2.0, -45.0)
    g = parse_client_args(['--corridor', '1', '2', '3'])
    assert (g['x'], g['y'], g['yaw_deg'], g['use_corridor_law']) == (1.0, 2.0, 3.0, True)
    g = parse_client_args(['1', '--no-corridor', '2', '3'])            # options between values
    assert (g['x'], g['y'], g['yaw_deg'], g['use_corridor_law']) == (1.0, 2.0, 3.0, False)
    for bad in (['1', '-inf', '0'], ['-nan', '0', '0']):
        with pytest.raises(UsageError) as e:
            parse_client_args(bad)
        assert 'not a finite number' in str(e.value)


def test_argparse_wording_for_a_missing_option_value():
    with pytest.raises(UsageError) as e:
        parse_client_args(['1', '2', '3', '--server-timeout'])
    assert str(e.value) == 'argument --server-timeout: expected one argument'


def test_the_obstacle_table_shows_how_sure_each_obstacle_is():
    from types import SimpleNamespace as NS
    from tiago_nav.mission.client import obstacle_rows, obstacle_table
    inf = float('inf')
    msg = NS(center=NS(x=10.736, y=-1.665), center_robot=NS(x=1.2, y=-0.5), radius=0.183,
             num_points=42, center_std=0.0112, radius_std=0.0031,
             center_robot_covariance=[0.0016 ** 2, 0.0, 0.0, 0.0027 ** 2])
    far = NS(center=NS(x=8.1, y=1.14), center_robot=NS(x=6.8, y=-1.0), radius=0.29,
             num_points=6, center_std=0.052, radius_std=inf,
             center_robot_covariance=[inf, 0.0, 0.0, inf])
    lines = obstacle_table(obstacle_rows([msg, far]))
    assert 'centre std' in lines[0] and 'radius std' in lines[0] and 'robot std' in lines[0]
    assert lines[2].split()[-3:] == ['±0.011', '±0.003', '±0.003']
    assert lines[3].split()[-3:] == ['±0.052', '?', '?']   # not known: said so, not a number
    # rows without the stds (6 columns) still print
    assert obstacle_table([(1.0, 2.0, 0.5, 0.1, 0.2, 9)])[2].split()[-3:] == ['?', '?', '?']
