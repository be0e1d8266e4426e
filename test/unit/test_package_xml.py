"""package.xml names every third-party module the code imports, by its rosdep key: the runtime's
(src/, nodes/) as exec_depend (or depend), the tests' as test_depend or exec_depend, so that
`rosdep install --from-paths . --ignore-src` installs what the package runs and tests with."""
import ast
import importlib.util
import os
import sys
import sysconfig
import xml.etree.ElementTree as ET

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

# module imported -> its rosdep key (None: no rosdep key exists; docs/getting-started.md#with-rosdep
# says how to install it)
KEYS = {
    'numpy': 'python3-numpy', 'scipy': 'python3-scipy', 'yaml': 'python3-yaml',
    'matplotlib': 'python3-matplotlib', 'pytest': 'python3-pytest', 'rospkg': 'python3-rospkg',
    'pybullet': 'python3-pybullet-pip', 'pybullet_utils': 'python3-pybullet-pip',
    'dask': None, 'distributed': None,
}
# ROS packages: the module is the package's name and its key
ROS = ('rospy', 'diagnostic_msgs', 'dynamic_reconfigure', 'rosgraph', 'roslaunch', 'rosbag', 'rosservice', 'rostest', 'roslib', 'actionlib',
       'tf2_ros', 'tf2_msgs', 'actionlib_msgs', 'geometry_msgs', 'move_base_msgs', 'nav_msgs',
       'rosgraph_msgs', 'sensor_msgs', 'std_msgs', 'std_srvs', 'visualization_msgs')
KEYS.update((m, m) for m in ROS)


def declared():
    """{tag: set of keys} of package.xml (depend counts as build, exec and test)."""
    root = ET.parse(os.path.join(ROOT, 'package.xml')).getroot()
    out = {}
    for e in root:
        out.setdefault(e.tag, set()).add(e.text.strip())
    both = out.get('depend', set())
    return {'exec': out.get('exec_depend', set()) | both,
            'test': out.get('test_depend', set()) | out.get('exec_depend', set()) | both}


def python_files(*dirs):
    for d in dirs:
        for folder, subdirs, files in os.walk(os.path.join(ROOT, d)):
            subdirs[:] = sorted(x for x in subdirs if x != '__pycache__')
            for f in sorted(files):
                path = os.path.join(folder, f)
                if f.endswith('.py') or (d == 'nodes' and '.' not in f):
                    yield path


def imported(paths):
    """{top-level module: first file importing it} over the given files (absolute imports)."""
    out = {}
    for path in paths:
        with open(path) as f:
            tree = ast.parse(f.read(), path)
        for node in ast.walk(tree):
            if isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom) and not node.level and node.module:
                names = [node.module]
            else:
                continue
            for n in names:
                out.setdefault(n.split('.')[0], os.path.relpath(path, ROOT))
    return out


def local_names():
    """Top-level modules of the repository itself: packages under src/, the tests' helpers."""
    names = set(os.listdir(os.path.join(ROOT, 'src')))
    for d in ('test/unit', 'test/ros'):
        names.update(f[:-3] for f in os.listdir(os.path.join(ROOT, d)) if f.endswith('.py'))
    return names


def is_stdlib(name):
    if name in sys.builtin_module_names:
        return True
    spec = importlib.util.find_spec(name)
    if spec is None or spec.origin is None:
        return False
    if spec.origin in ('built-in', 'frozen'):
        return True
    stdlib = os.path.realpath(sysconfig.get_paths()['stdlib'])
    origin = os.path.realpath(spec.origin)
    return origin.startswith(stdlib + os.sep) and 'site-packages' not in origin \
        and 'dist-packages' not in origin


def missing(dirs, kind, have=None):
    """What the files under dirs import without a key in have (default: package.xml's)."""
    have = declared()[kind] if have is None else have
    local = local_names()
    out = []
    for name, where in sorted(imported(python_files(*dirs)).items()):
        if name in local or name == '__future__':
            continue
        if name in KEYS:
            key = KEYS[name]
            if key is not None and key not in have:
                out.append('%s (%s): no %s_depend %s' % (name, where, kind, key))
        elif not is_stdlib(name):
            out.append('%s (%s): not in this test\'s table of rosdep keys' % (name, where))
    return out


def test_runtime_imports_have_exec_depends():
    assert missing(('src', 'nodes'), 'exec') == []


def test_test_imports_have_test_or_exec_depends():
    assert missing(('test/unit', 'test/ros'), 'test') == []


def test_a_missing_key_is_reported():
    have = declared()['exec'] - {'python3-pybullet-pip'}
    found = missing(('src', 'nodes'), 'exec', have)
    assert any(m.startswith('pybullet ') and 'python3-pybullet-pip' in m for m in found), found
