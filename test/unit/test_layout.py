"""The package's layering (docs/development.md, Layout): which folder of the runtime package
(src/tiago_nav) may import which, that only the ROS adapter layer imports ROS, that the runtime
never imports the tooling (src/tiago_nav_tools), that the module import graph has no cycle
(imports inside functions counted), and that nodes/ holds node wiring only."""
import ast
import os

import pytest

from conftest import ROOT

SRC = os.path.join(ROOT, 'src')
RUNTIME = os.path.join(SRC, 'tiago_nav')
ADAPTER = ('ros', 'nodes')      # runtime folders allowed to import ROS (the tooling may too)
ROS_MODULES = ('rospy', 'actionlib', 'actionlib_msgs', 'tf2_ros', 'tf2_msgs', 'tf', 'rosgraph',
               'rosgraph_msgs', 'roslaunch', 'rostest', 'rosnode', 'rosservice', 'rosbag', 'genpy',
               'geometry_msgs', 'nav_msgs', 'sensor_msgs', 'std_msgs', 'std_srvs',
               'visualization_msgs', 'move_base_msgs', 'diagnostic_msgs', 'dynamic_reconfigure',
               'tiago_nav.msg', 'tiago_nav.srv', 'tiago_nav.cfg')

# Which layer may import which. A layer is a folder of src/tiago_nav; ``core`` is the shared
# helpers at its top (geometry, grid, scan, parameters, clocks, lockstep rules), ``tools`` the
# whole of src/tiago_nav_tools. Each layer may import itself. The simulator imports no detection
# or localisation: what the evaluator judges it by (in view, matching) is tooling.
ALLOWED = {
    'core': set(),
    'sim': {'core'},
    'localisation': {'core'},
    'nav': {'core'},
    'corridor': {'core'},
    'detection': {'core', 'localisation'},
    'mission': {'core', 'corridor'},
    'ros': {'core', 'sim', 'nav'},
    'nodes': {'core', 'sim', 'localisation', 'nav', 'corridor', 'detection', 'mission', 'ros'},
    'tools': {'core', 'sim', 'localisation', 'nav', 'corridor', 'detection', 'mission', 'ros',
              'nodes'},
}


def module_files():
    """{dotted module name: path} of every module of tiago_nav and tiago_nav_tools."""
    out = {}
    for package in ('tiago_nav', 'tiago_nav_tools'):
        for d, dirs, files in os.walk(os.path.join(SRC, package)):
            dirs[:] = [x for x in dirs if x != '__pycache__']
            for f in files:
                if f.endswith('.py'):
                    rel = os.path.relpath(os.path.join(d, f), SRC)[:-3].split(os.sep)
                    out['.'.join(rel[:-1] if rel[-1] == '__init__' else rel)] = os.path.join(d, f)
    return out


def imported_names(name, path):
    """Every name ``name`` (a module at ``path``) imports, anywhere in it (inside functions
    too): ``import a.b`` gives ``a.b``; ``from a import b`` gives ``a`` and ``a.b``; relative
    imports resolved."""
    with open(path) as f:
        tree = ast.parse(f.read(), path)
    package = name.split('.') if path.endswith('__init__.py') else name.split('.')[:-1]
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for a in node.names:
                yield a.name
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package[:len(package) - node.level + 1] + ([node.module] if node.module else [])
                module = '.'.join(base)
            else:
                module = node.module
            yield module
            for a in node.names:
                yield '%s.%s' % (module, a.name)


def graph(files):
    """{module: set of the package's modules it imports}."""
    return {m: {n for n in imported_names(m, p) if n in files and n != m} for m, p in files.items()}


def layer(module):
    parts = module.split('.')
    if parts[0] == 'tiago_nav_tools':
        return 'tools'
    if len(parts) > 1 and os.path.isdir(os.path.join(RUNTIME, parts[1])):
        return parts[1]
    return 'core'


def is_ros(name):
    return any(name == m or name.startswith(m + '.') for m in ROS_MODULES) \
        or name.split('.')[0].endswith('_msgs')


def layering_violations(files, g):
    bad = []
    for m, deps in sorted(g.items()):
        for d in sorted(deps):
            if layer(d) != layer(m) and layer(d) not in ALLOWED[layer(m)]:
                bad.append('%s (%s) imports %s (%s)' % (m, layer(m), d, layer(d)))
    return bad


def cycles(g):
    """The strongly connected components of more than one module (Tarjan, iterative)."""
    index, low, on, stack, out, counter = {}, {}, set(), [], [], [0]
    for root in sorted(g):
        if root in index:
            continue
        work = [(root, iter(sorted(g[root])))]
        index[root] = low[root] = counter[0]
        counter[0] += 1
        stack.append(root)
        on.add(root)
        while work:
            v, it = work[-1]
            w = next(it, None)
            if w is not None:
                if w not in index:
                    index[w] = low[w] = counter[0]
                    counter[0] += 1
                    stack.append(w)
                    on.add(w)
                    work.append((w, iter(sorted(g[w]))))
                elif w in on:
                    low[v] = min(low[v], index[w])
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[v])
            if low[v] == index[v]:
                comp = []
                while True:
                    w = stack.pop()
                    on.discard(w)
                    comp.append(w)
                    if w == v:
                        break
                if len(comp) > 1:
                    out.append(sorted(comp))
    return out


def not_wiring(path):
    """The top-level functions and classes of a nodes/ module that are not node wiring. The
    rule: each of them uses, in its own body, a name the module imports from ROS (rospy,
    actionlib, tf2_ros, a message package, the generated messages) or from the ROS adapter
    layer (tiago_nav.ros); ``main``, the parameter dataclass ``Params`` (the node's parameters,
    parsed by the adapter layer), a plain record (a class of annotated fields and nothing else,
    e.g. the node's publishers) and an exception type (a class whose base's name ends in
    ``Error``) are wiring by definition. Anything else is a decision or a computation on plain
    values and belongs in the library."""
    with open(path) as f:
        tree = ast.parse(f.read(), path)
    ros_names = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            ros_names |= {(a.asname or a.name).split('.')[0] for a in node.names if is_ros(a.name)}
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0 and \
                (is_ros(node.module) or node.module.startswith('tiago_nav.ros')):
            ros_names |= {a.asname or a.name for a in node.names}
    bad = []
    for node in tree.body:
        if not isinstance(node, (ast.FunctionDef, ast.ClassDef)) or node.name in ('main', 'Params'):
            continue
        if isinstance(node, ast.ClassDef) and (
                all(isinstance(x, ast.AnnAssign) or isinstance(x, ast.Expr) for x in node.body)
                or any(getattr(b, 'id', '').endswith('Error') for b in node.bases)):
            continue
        if not any(isinstance(x, ast.Name) and x.id in ros_names for x in ast.walk(node)):
            bad.append(node.name)
    return bad


def test_every_folder_has_a_row():
    folders = {d for d in os.listdir(RUNTIME)
               if os.path.isdir(os.path.join(RUNTIME, d)) and d != '__pycache__'}
    assert folders | {'core', 'tools'} == set(ALLOWED), \
        'src/tiago_nav folders without a row in ALLOWED (or rows without a folder): %s' \
        % sorted(folders ^ (set(ALLOWED) - {'core', 'tools'}))


def test_each_layer_imports_only_what_it_may():
    files = module_files()
    bad = layering_violations(files, graph(files))
    assert not bad, 'imports against the layering (ALLOWED):\n' + '\n'.join(bad)


def test_the_runtime_never_imports_the_tooling():
    files = module_files()
    bad = ['%s: %s' % (m, n) for m, p in sorted(files.items()) if layer(m) != 'tools'
           for n in imported_names(m, p) if n.split('.')[0] == 'tiago_nav_tools']
    assert not bad, '\n'.join(bad)


def test_only_the_adapter_layer_imports_ros():
    files = module_files()
    bad = ['%s: %s' % (m, n) for m, p in sorted(files.items())
           if layer(m) not in ADAPTER + ('tools',) for n in imported_names(m, p) if is_ros(n)]
    assert not bad, 'ROS imported outside the adapter layer:\n' + '\n'.join(bad)


def test_the_import_graph_has_no_cycle():
    found = cycles(graph(module_files()))
    assert not found, 'import cycles (imports inside functions counted):\n' + \
        '\n'.join(' <-> '.join(c) for c in found)


def test_nodes_hold_wiring_only():
    nodes = os.path.join(RUNTIME, 'nodes')
    bad = ['%s: %s' % (f, ', '.join(names)) for f in sorted(os.listdir(nodes))
           if f.endswith('.py') and not f.startswith('__')
           for names in [not_wiring(os.path.join(nodes, f))] if names]
    assert not bad, 'decisions in nodes/ (move them into the library):\n' + '\n'.join(bad)


def test_the_checks_can_fail(tmp_path):
    """Each rule above finds a planted violation."""
    g = {'tiago_nav.sim.a': {'tiago_nav.detection.b'}, 'tiago_nav.detection.b': {'tiago_nav.geometry'},
         'tiago_nav.geometry': set(), 'tiago_nav.detection.c': {'tiago_nav_tools.docs'}}
    assert layering_violations({}, g) == [
        'tiago_nav.detection.c (detection) imports tiago_nav_tools.docs (tools)',
        'tiago_nav.sim.a (sim) imports tiago_nav.detection.b (detection)']
    assert cycles({'a': {'b'}, 'b': {'c'}, 'c': {'a'}, 'd': {'a'}}) == [['a', 'b', 'c']]
    assert cycles({'a': {'b'}, 'b': {'c'}, 'c': set()}) == []
    node = tmp_path / 'planted.py'
    node.write_text('import rospy\nfrom tiago_nav.ros.params import read_or_exit\n\n\n'
                    'def wired():\n    return rospy.get_name()\n\n\n'
                    'def adapted():\n    return read_or_exit\n\n\n'
                    'def decide(a, b):\n    return a < b\n\n\nclass Params:\n    pass\n\n\n'
                    'class Outputs:\n    \"\"\"Publishers.\"\"\"\n    scan: object\n\n\n'
                    'class NotReady(RuntimeError):\n    pass\n\n\n'
                    'class Judge:\n    def verdict(self, x):\n        return x > 0\n\n\n'
                    'def main():\n    pass\n')
    assert not_wiring(str(node)) == ['decide', 'Judge']
    mod = tmp_path / 'inner.py'
    mod.write_text('def f():\n    from tiago_nav.sim import scene\n')
    assert list(imported_names('tiago_nav.detection.inner', str(mod))) == [
        'tiago_nav.sim', 'tiago_nav.sim.scene']


def test_executables_are_doors():
    for folder, names in (('nodes', os.listdir(os.path.join(ROOT, 'nodes'))), ('scripts', ['evaluate'])):
        for name in names:
            with open(os.path.join(ROOT, folder, name)) as f:
                lines = f.read().splitlines()
            assert len(lines) <= 15, '%s/%s has %d lines' % (folder, name, len(lines))
            assert any('tiago_nav.nodes' in line or 'tiago_nav_tools.evaluate' in line
                       for line in lines), name


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


if __name__ == '__main__':
    pytest.main([__file__, '-q'])
