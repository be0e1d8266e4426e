"""The package's layering rule (tiago_nav/__init__.py): only the ROS adapter layer imports ROS,
and product modules never import the test support."""
import ast
import os

from conftest import ROOT

SRC = os.path.join(ROOT, 'src', 'tiago_nav')
ADAPTER = ('ros', 'nodes', 'testing')      # subpackages allowed to import ROS
ROS_MODULES = ('rospy', 'actionlib', 'actionlib_msgs', 'tf2_ros', 'tf2_msgs', 'tf', 'rosgraph',
               'rosgraph_msgs', 'roslaunch', 'rostest', 'rosnode', 'rosservice', 'genpy',
               'geometry_msgs', 'nav_msgs', 'sensor_msgs', 'std_msgs', 'std_srvs',
               'visualization_msgs', 'move_base_msgs', 'dynamic_reconfigure', 'tiago_nav.msg',
               'tiago_nav.srv', 'tiago_nav.cfg')


def imports(path):
    with open(path) as f:
        tree = ast.parse(f.read(), path)
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for a in node.names:
                yield a.name
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            yield node.module
            for a in node.names:
                yield '%s.%s' % (node.module, a.name)


def library_modules():
    for d, _, files in os.walk(SRC):
        rel = os.path.relpath(d, SRC).split(os.sep)
        if rel[0] in ADAPTER:
            continue
        for f in files:
            if f.endswith('.py'):
                yield os.path.join(d, f)


def is_ros(name):
    return any(name == m or name.startswith(m + '.') for m in ROS_MODULES) \
        or name.split('.')[0].endswith('_msgs')


def test_library_imports_no_ros():
    bad = ['%s: %s' % (os.path.relpath(p, SRC), n) for p in library_modules() for n in imports(p)
           if is_ros(n)]
    assert not bad, 'ROS imported outside the adapter layer:\n' + '\n'.join(bad)


def test_product_never_imports_the_test_support():
    bad = []
    for d, _, files in os.walk(SRC):
        # the batch evaluator is test tooling: it judges runs with the testing helpers
        if os.path.relpath(d, SRC).split(os.sep)[0] in ('testing', 'evaluate'):
            continue
        for f in files:
            if f.endswith('.py'):
                p = os.path.join(d, f)
                bad += ['%s: %s' % (os.path.relpath(p, SRC), n) for n in imports(p)
                        if n.startswith('tiago_nav.testing')]
    assert not bad, '\n'.join(bad)


def test_library_never_imports_the_adapter_layer():
    bad = ['%s: %s' % (os.path.relpath(p, SRC), n) for p in library_modules() for n in imports(p)
           if n.startswith(('tiago_nav.ros', 'tiago_nav.nodes'))
           and not n.startswith('tiago_nav.robot')]
    assert not bad, '\n'.join(bad)


def test_executables_are_doors():
    for name in os.listdir(os.path.join(ROOT, 'nodes')):
        with open(os.path.join(ROOT, 'nodes', name)) as f:
            lines = f.read().splitlines()
        assert len(lines) <= 15, '%s has %d lines' % (name, len(lines))
        assert any('tiago_nav.nodes' in line for line in lines), name


def test_nodes_run_one_blas_thread():
    """Importing the nodes' package before numpy pins BLAS to one thread (spinning BLAS
    workers cost whole cores), and keeps a value the user set."""
    import subprocess
    import sys
    code = ('import os, tiago_nav.nodes, numpy; '
            'print(os.environ["OPENBLAS_NUM_THREADS"], os.environ["OMP_NUM_THREADS"])')
    env = {k: v for k, v in os.environ.items() if k not in ('OPENBLAS_NUM_THREADS', 'OMP_NUM_THREADS')}
    env['PYTHONPATH'] = os.path.join(ROOT, 'src') + os.pathsep + env.get('PYTHONPATH', '')
    assert subprocess.check_output([sys.executable, '-c', code], env=env, text=True).split() == ['1', '1']
    env['OMP_NUM_THREADS'] = '2'
    assert subprocess.check_output([sys.executable, '-c', code], env=env, text=True).split() == ['1', '2']
