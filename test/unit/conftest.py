"""Makes the library importable from the source tree (no ROS master needed). The generated
message modules (``tiago_nav.msg``, ``tiago_nav.srv``) live in the catkin workspace's devel space
(``.ws/``, or the sourced workspace's on ``PYTHONPATH``): when it has been built, they are joined
to the package so the node modules import too.

The ``ros`` marker: tests that need ROS 1's Python packages (rospy, actionlib, tf2_ros, message
packages) or the built workspace. ``-m "not ros"`` runs the library tests alone, where ROS is
absent (test/platforms/noetic_python.sh). A test file that needs ROS to be imported at all says
so with a top-level ``pytestmark = pytest.mark.ros`` (or a list starting with it): such files
are not even imported when ``ros`` is deselected, and the summary names them.
"""
import glob
import os
import re
import shutil
import sys

import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
sys.path.insert(0, os.path.join(ROOT, 'src'))
# only the virtualenv of this Python: another version's compiled modules would not load here
for sp in sorted(glob.glob(os.path.join(ROOT, '.venv', 'lib', 'python%d.%d' % sys.version_info[:2],
                                        'site-packages'))):
    if sp not in sys.path:
        sys.path.append(sp)
import tiago_nav  # noqa: E402

# this repository's .ws (make setup), or the sourced workspace the package is built in (a catkin
# workspace of the user's, `rosdep install` and catkin_make): its devel space is on PYTHONPATH
_devel = glob.glob(os.path.join(ROOT, '.ws', 'devel', 'lib', 'python3*', 'dist-packages', 'tiago_nav'))
_devel += [os.path.join(p, 'tiago_nav') for p in os.environ.get('PYTHONPATH', '').split(os.pathsep)
           if p and os.path.isdir(os.path.join(p, 'tiago_nav', 'msg'))]
for d in _devel:
    if d not in tiago_nav.__path__:
        tiago_nav.__path__.append(d)
WORLDS = os.path.join(ROOT, 'worlds')
# the tests that start the package's nodes skip (with WORKSPACE_REASON) where this is true:
# no roscore, or no workspace with the package on the ROS paths
NO_WORKSPACE = shutil.which('roscore') is None or (
    'tiago_nav' not in os.environ.get('ROS_PACKAGE_PATH', '')
    and not os.environ.get('CMAKE_PREFIX_PATH', '').count('.ws'))
WORKSPACE_REASON = 'needs the sourced workspace (source .ws/devel/setup.bash)'

ROS_MODULE = re.compile(r'^pytestmark = \[?pytest\.mark\.ros\b', re.M)
_not_collected = []


def pytest_configure(config):
    config.addinivalue_line('markers', 'ros: needs ROS 1 (rospy, actionlib, tf2_ros, message '
                                       'packages) or the built workspace')


class _Marks(dict):
    def __missing__(self, name):
        return name == 'ros'


def ros_deselected(config):
    """True if the ``-m`` expression leaves out tests marked ``ros`` (and only ``ros``)."""
    expr = (config.getoption('markexpr', '') or '').strip()
    if not expr:
        return False
    try:
        return not eval(expr, {'__builtins__': {}}, _Marks())     # noqa: S307 (and/or/not of names)
    except Exception:                                              # noqa: BLE001 (pytest reports it)
        return False


def _ignore(path, config):
    if not (path.endswith('.py') and os.path.basename(path).startswith('test_')) \
            or not ros_deselected(config):
        return None
    with open(path) as f:
        if ROS_MODULE.search(f.read()):
            _not_collected.append(os.path.basename(path))
            return True
    return None


# the hook's path argument: a py.path before pytest 7 (Noetic's pytest is 4.6), a pathlib.Path since
if int(pytest.__version__.split('.')[0]) >= 7:
    def pytest_ignore_collect(collection_path, config):
        return _ignore(str(collection_path), config)
else:
    def pytest_ignore_collect(path, config):
        return _ignore(str(path), config)


def pytest_terminal_summary(terminalreporter):
    if _not_collected:
        terminalreporter.write_line('not imported (need ROS, -m "%s"): %s' % (
            terminalreporter.config.getoption('markexpr'), ', '.join(sorted(set(_not_collected)))))
