"""Every module under src/tiago_nav and src/tiago_nav_tools imports. Where ROS 1 is absent (Noetic's Python emulated
without ROS, test/platforms/noetic_python.sh) a module may fail only for want of a ROS package
listed here: it is then skipped by name, with the package it needs. Where rospy imports, every
module must, and so must the generated messages once the workspace is built."""
import importlib
import importlib.util
import os

import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
SRC = os.path.join(ROOT, 'src')

# ROS 1's Python packages (Noetic's ros-noetic-*, Debian's python3-*) that the package imports, and
# the ROS-side code generators and tools they bring; none of them is on PyPI as Noetic ships it.
ROS_PACKAGES = frozenset((
    'rospy', 'rosgraph', 'roslaunch', 'rosservice', 'rostopic', 'rosnode', 'rosbag', 'rostest',
    'rosunit', 'roslib', 'rospkg', 'genpy', 'genmsg', 'catkin', 'catkin_pkg', 'actionlib',
    'tf2_ros', 'tf2_py', 'tf2_msgs', 'actionlib_msgs', 'geometry_msgs', 'move_base_msgs',
    'nav_msgs', 'rosgraph_msgs', 'sensor_msgs', 'std_msgs', 'std_srvs', 'visualization_msgs',
    'dynamic_reconfigure'))
# generated from msg/, srv/, action/ and cfg/ by the catkin build (the workspace's devel space)
GENERATED = ('tiago_nav.msg', 'tiago_nav.srv', 'tiago_nav.cfg')


def modules():
    """Dotted names of every module under src/tiago_nav and src/tiago_nav_tools, sorted."""
    names = []
    for package in ('tiago_nav', 'tiago_nav_tools'):
        for d, dirs, files in os.walk(os.path.join(SRC, package)):
            dirs[:] = sorted(x for x in dirs if x != '__pycache__')
            for f in files:
                if f.endswith('.py'):
                    rel = os.path.relpath(os.path.join(d, f), SRC)[:-3].split(os.sep)
                    names.append('.'.join(rel[:-1] if rel[-1] == '__init__' else rel))
    return sorted(names)


def ros_present():
    return importlib.util.find_spec('rospy') is not None


def missing_ros(e):
    """The ROS package (or generated module) whose absence an ImportError reports, else None."""
    name = getattr(e, 'name', None) or ''
    if name.split('.')[0] in ROS_PACKAGES or name.startswith(GENERATED):
        return name
    return None


def try_import(name):
    """(``'ok'`` | ``'ros'`` | ``'error'``, detail) for one module."""
    try:
        importlib.import_module(name)
    except ImportError as e:
        need = missing_ros(e)
        if need is None:
            return 'error', '%s: %s' % (type(e).__name__, e)
        if need.startswith(GENERATED) and ros_present():
            return 'workspace', need
        return ('error', 'ROS is here, yet: %s: %s' % (type(e).__name__, e)) if ros_present() \
            else ('ros', need)
    except Exception as e:      # noqa: BLE001 (anything else a module raises on import fails it)
        return 'error', '%s: %s' % (type(e).__name__, e)
    return 'ok', ''


def test_the_module_list_is_complete():
    assert {'tiago_nav', 'tiago_nav.nodes.simulator', 'tiago_nav_tools.evaluate.main'} <= set(modules())


@pytest.mark.parametrize('name', modules())
def test_module_imports(name):
    status, detail = try_import(name)
    if status == 'ros':
        pytest.skip('%s is ROS-facing: needs %s (not installed here)' % (name, detail))
    if status == 'workspace':
        pytest.skip('%s needs the built workspace (make setup) for %s' % (name, detail))
    assert status == 'ok', '%s: %s' % (name, detail)



def bench_imports():
    """``(script, module, name)`` for each name a bench/ script imports from this package
    (``name`` None for a plain ``import module``): the scripts run only under ``make bench``,
    so a module moved or renamed would otherwise break them unseen."""
    import ast
    import glob
    out = []
    for path in sorted(glob.glob(os.path.join(ROOT, 'bench', '*.py'))
                       + glob.glob(os.path.join(ROOT, 'bench', '*', '*.py'))):
        with open(path) as f:
            tree = ast.parse(f.read(), path)
        script = os.path.relpath(path, ROOT)
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom) and node.level == 0 and node.module \
                    and node.module.split('.')[0] in ('tiago_nav', 'tiago_nav_tools'):
                out += [(script, node.module, a.name) for a in node.names]
            elif isinstance(node, ast.Import):
                out += [(script, a.name, None) for a in node.names
                        if a.name.split('.')[0] in ('tiago_nav', 'tiago_nav_tools')]
    return out


def test_bench_scripts_import_from_the_package():
    assert any(s == 'bench/bench_shapes.py' for s, _, _ in bench_imports())


@pytest.mark.parametrize('script,module,name', bench_imports(),
                         ids=lambda v: v if isinstance(v, str) else '')
def test_bench_script_imports_resolve(script, module, name):
    status, detail = try_import(module)
    if status in ('ros', 'workspace'):
        pytest.skip('%s needs %s' % (module, detail))
    assert status == 'ok', '%s: %s: %s' % (script, module, detail)
    if name is not None:
        mod = importlib.import_module(module)
        assert hasattr(mod, name) or try_import(module + '.' + name)[0] == 'ok', \
            '%s: %s has no %s' % (script, module, name)
