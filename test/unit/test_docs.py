"""The documentation: the generated pages are what the code generates (``make docs`` rewrites
them), the ROS API declaration covers every interface parameter, no relative link is broken,
the README stays short, and ``make bench`` writes every result the pages show."""
import glob
import importlib
import os
import re
import sys

import pytest

from tiago_nav_tools import benchmarks, docs
from tiago_nav.params import param_fields
from tiago_nav_tools.interfaces import NODES, SECTIONS

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
README_MAX_LINES = 250


def _read(rel):
    with open(os.path.join(ROOT, rel)) as f:
        return f.read()


@pytest.mark.ros                 # the node modules (their Params) import rospy
def test_ros_api_page_is_what_the_code_generates():
    assert _read(docs.ROS_API) == docs.ros_api_page(ROOT), \
        'docs/ros_api.md is stale: run `make docs` and commit it'


def test_benchmarks_page_is_the_render_of_the_results():
    assert _read(docs.BENCHMARKS) == docs.benchmarks_page(ROOT), \
        'docs/benchmarks.md is stale: run `make docs` and commit it'


@pytest.mark.ros
def test_docs_check_mode_agrees(capsys):
    assert docs.main(['--check', '--root', ROOT]) == 0


@pytest.mark.ros
@pytest.mark.parametrize('entry', [e for e in NODES if e['params']], ids=lambda e: e['node'])
def test_every_interface_parameter_is_declared(entry):
    cls = docs.node_params(entry)
    declared = docs.referenced_params(entry)
    missing = [n for n in docs.interface_params(cls) if n not in declared]
    assert not missing, '%s: parameters %s name ROS interfaces that src/tiago_nav_tools/interfaces.py ' \
        'does not declare' % (entry['node'], missing)
    unknown = declared - {n for n, _ in param_fields(cls)}
    assert not unknown, '%s: interfaces.py names {%s}, not parameters of %s.Params' \
        % (entry['node'], ', '.join(sorted(unknown)), entry['params'])


@pytest.mark.ros
def test_every_node_module_is_declared():
    """A node module with a Params dataclass is on the page (the client has none)."""
    modules = {os.path.splitext(os.path.basename(p))[0]
               for p in glob.glob(os.path.join(ROOT, 'src', 'tiago_nav', 'nodes', '*.py'))}
    modules -= {'__init__', '__main__'}
    declared = {e['params'].rsplit('.', 1)[1] for e in NODES if e['params']} | \
        {e['executable'] for e in NODES if not e['params']}
    assert modules <= declared | {e['executable'] for e in NODES}, modules - declared
    for e in NODES:
        assert os.path.exists(os.path.join(ROOT, 'nodes', e['executable'])), e['executable']
        assert os.path.exists(os.path.join(ROOT, 'launch', e['launch'])), e['launch']
        assert set(e) <= {'node', 'executable', 'params', 'launch', 'summary'} | \
            {k for k, _ in SECTIONS}, e['node']
        if e['params']:
            importlib.import_module(e['params']).Params


def test_every_launch_argument_is_documented():
    for path in sorted(glob.glob(os.path.join(ROOT, 'launch', '*.launch'))):
        for name, _, doc, _ in docs.launch_args(path):
            assert doc.strip(), '%s: <arg name="%s"> has no doc=' % (os.path.basename(path), name)


# --- links and length ----------------------------------------------------------------------
_LINK = re.compile(r'!?\[[^\]]*\]\(\s*<?([^)\s>]+)>?(?:\s+"[^"]*")?\s*\)')
_FENCE = re.compile(r'^(```|~~~).*?^\1', re.S | re.M)
_CODE = re.compile(r'`[^`\n]*`')


def slug(heading):
    """GitHub's anchor of a heading."""
    text = re.sub(r'[^\w\- ]', '', heading.strip().lower())
    return text.replace(' ', '-')


def anchors(path):
    with open(path) as f:
        text = _FENCE.sub('', f.read())
    seen, out = {}, set()
    for m in re.finditer(r'^#{1,6}\s+(.*?)\s*#*\s*$', text, re.M):
        s = slug(m.group(1))
        n = seen.get(s, 0)
        seen[s] = n + 1
        out.add(s if n == 0 else '%s-%d' % (s, n))
    out.update(re.findall(r'<a\s+(?:name|id)="([^"]+)"', text))
    return out


def broken_links(path):
    """The relative links of a Markdown file whose target (or heading anchor) does not exist."""
    with open(path) as f:
        text = _CODE.sub('', _FENCE.sub('', f.read()))
    bad = []
    for target in _LINK.findall(text):
        if re.match(r'^[a-z][a-z0-9+.-]*:', target, re.I):     # http:, mailto:, ...
            continue
        rel, _, anchor = target.partition('#')
        dest = os.path.normpath(os.path.join(os.path.dirname(path), rel)) if rel else path
        if not os.path.exists(dest):
            bad.append(target)
        elif anchor and dest.endswith('.md') and anchor not in anchors(dest):
            bad.append(target + ' (no such heading)')
    return bad


def _markdown_files():
    return [p for p in [os.path.join(ROOT, 'README.md')] +
            sorted(glob.glob(os.path.join(ROOT, 'docs', '*.md'))) if os.path.exists(p)]


@pytest.mark.parametrize('path', _markdown_files(), ids=lambda p: os.path.relpath(p, ROOT))
def test_no_broken_relative_link(path):
    bad = broken_links(path)
    assert not bad, '%s: broken links: %s' % (os.path.relpath(path, ROOT), ', '.join(bad))


def test_broken_link_finder(tmp_path):
    (tmp_path / 'a.md').write_text('# Top\n## Two words\n[ok](a.md#two-words) [self](#top) '
                                   '[gone](b.md) [bad anchor](#nope) [web](https://x.org/y) '
                                   '`[code](c.md)`\n```\n[fenced](d.md)\n```\n')
    assert broken_links(str(tmp_path / 'a.md')) == ['b.md', '#nope (no such heading)']


def test_readme_is_short():
    n = len(_read('README.md').splitlines())
    assert n <= README_MAX_LINES, 'README.md has %d lines (at most %d: the reference belongs ' \
        'in docs/)' % (n, README_MAX_LINES)



def test_the_noetic_pip_line_is_one_line_everywhere():
    """test/platforms/noetic_python.sh runs README.md's line; getting-started.md shows the same."""
    lines = [[x for x in _read(f).splitlines() if x.startswith('pip3 install --user ')]
             for f in ('README.md', os.path.join('docs', 'getting-started.md'))]
    assert len(lines[0]) == 1 and lines[0] == lines[1], lines

# --- benchmarks ----------------------------------------------------------------------------
def test_every_benchmark_script_is_run_by_make_bench():
    run = {cmd.split()[0] for _, _, runs in benchmarks.BENCHMARKS for cmd, _ in runs}
    scripts = {os.path.relpath(p, ROOT) for p in glob.glob(os.path.join(ROOT, 'bench', 'bench_*.py'))}
    assert scripts <= run, 'not run by make bench: %s' % (scripts - run)
    for script in run:
        assert os.path.exists(os.path.join(ROOT, script)), script


def test_make_bench_writes_every_result_the_docs_cite():
    written = {f for _, _, runs in benchmarks.BENCHMARKS for _, files in runs for f in files}
    cited = set()
    for path in _markdown_files():
        with open(path) as f:
            cited.update(re.findall(r'bench/results/(\w+\.json)', f.read()))
    assert cited <= written, 'cited but not written by make bench: %s' % (cited - written)
    for f in written:
        assert os.path.exists(os.path.join(ROOT, 'bench', 'results', f)), f


def test_each_benchmark_command_names_its_output():
    """A run that writes somewhere other than its script's default says so with --out."""
    for name, _, runs in benchmarks.BENCHMARKS:
        for cmd, files in runs:
            if '--out' in cmd:
                assert cmd.split('--out', 1)[1].split()[0] == 'bench/results/' + files[0]


def test_bench_scripts_record_meta():
    for path in glob.glob(os.path.join(ROOT, 'bench', 'bench_*.py')) + \
            [os.path.join(ROOT, 'scripts', 'run_demo.py')]:
        with open(path) as f:
            assert "['meta'] = " in f.read(), '%s writes no meta block' % path


def test_meta_block():
    m = benchmarks.meta({'quick': True, 'n': 3}, real_time_factor=0.0, laser_model='tiago',
                        odometry_model='drift', quick=True,
                        argv=[os.path.join(ROOT, 'bench', 'bench_x.py'), '--quick'])
    assert set(m) == {'commit', 'date', 'command', 'cores', 'loadavg', 'platform',
                      'real_time_factor', 'laser_model', 'odometry_model', 'quick', 'options'}
    assert m['command'] == 'bench/bench_x.py --quick'
    assert re.match(r'^\d{4}-\d\d-\d\dT\d\d:\d\d:\d\dZ$', m['date'])
    assert m['cores'] == os.cpu_count() and len(m['loadavg']) == 3
    assert m['quick'] is True and m['options'] == {'quick': True, 'n': 3}
    if m['commit'] is not None:
        assert re.match(r'^[0-9a-f]{40}(-dirty)?$', m['commit'])


def test_meta_block_names_the_platform():
    import platform
    import numpy
    p = benchmarks.meta()['platform']
    assert p['python'] == platform.python_version()
    assert p['packages']['numpy'] == numpy.__version__
    if os.path.exists('/etc/os-release'):
        with open('/etc/os-release') as f:
            assert 'PRETTY_NAME="%s"' % p['os'] in f.read()
    line = benchmarks.platform_line(p)
    assert line.startswith(p['os']) and 'numpy %s' % numpy.__version__ in line
    assert benchmarks.platform_line(None) == 'platform not recorded (Debian 12)'


def test_launch_models_follow_launch_arguments():
    assert benchmarks.launch_models([], ROOT) == ('tiago', 'drift')
    assert benchmarks.launch_models(['laser_model:=ideal'], ROOT) == ('ideal', 'drift')


def test_benchmarks_page_says_when_meta_is_missing():
    assert benchmarks.meta_lines({'x': 1}) == ['meta: not recorded']
    line = benchmarks.meta_lines({'meta': benchmarks.meta(argv=['bench/b.py'])})[0]
    assert line.startswith('meta: commit') and '`bench/b.py`' in line


def test_every_benchmark_says_what_it_measures():
    for name in benchmarks.NAMES:
        assert benchmarks.ABOUT.get(name, '').strip(), '%s: no entry in benchmarks.ABOUT' % name
    page = docs.benchmarks_page(ROOT)
    for name, title, _ in benchmarks.BENCHMARKS:
        assert '## %s\n\n%s\n' % (title, benchmarks.ABOUT[name]) in page, name


def test_detection_sensing_is_rendered_from_its_own_structure():
    """bench_detection_sensing.py writes scene sets of detector variants, not detection.json's
    per-world methods: each variant is a row with its figures."""
    variant = {'scenes': 20, 'must_find': 80, 'missed': 1, 'false_positives': 0,
               'rms_error_m': 0.0114, 'max_error_m': 0.0195, 'beyond_tolerance': 2,
               'corrected_fraction': 1.0, 'latency_ms_median': 30.4, 'cpu_ms_median': 10.5}
    data = {'laser_model': 'tiago', 'noise_std_m': 0.01, 'min_beams': 10, 'tolerance_m': 0.03,
            'course': {'localisation_error_m_rms': 0.0133, 'correction_on': variant,
                       'correction_off': dict(variant, rms_error_m=0.0115), 'before': variant},
            'missions': {'localisation_error_m_rms': 0.0149, 'correction_on': variant}}
    lines = benchmarks.RENDER_FILE['detection_sensing.json'](data)
    rows = [ln for ln in lines if ln.startswith('| ') and not ln.startswith('| scene set')]
    assert len(rows) == 4, lines
    assert '| course pose B | pose correction off | 20 | 0.0133 | 80 | 1 | 0 | 0.0115 |' in rows[1]
    assert rows[3].startswith('| random poses B | pose correction on |')


def test_obstacle_detector_comparison_is_rendered_or_its_skip_explained():
    """detection.json's comparison with obstacle_detector: a row per detector with its figures,
    or, when the package was not installed, the reason it was skipped."""
    ours = {'must_find': 80, 'found': 80, 'rms_error_m': 0.0083, 'max_error_m': 0.0147,
            'false_positives': 0, 'false_positives_off_map': 0}
    theirs = dict(ours, rms_error_m=0.051, max_error_m=0.0729, false_positives=3)
    rest = dict(ours, rms_error_m=0.0071)
    ran = benchmarks.render_detection({'obstacle_detector': {
        'skipped': False, 'laser_model': 'tiago', 'scans': 20, 'truth_pose': [11.0, 0.0, -0.8],
        'tiago_nav_one_scan': ours, 'tiago_nav': rest, 'obstacle_detector': theirs,
        'rms_ratio': 6.14, 'rms_ratio_rest': 7.18, 'rest_scans_used': [5] * 20}})
    assert '| tiago_nav, the one scan | 80/80 | 0 (0) | 0.0083 | 0.0147 |' in ran
    assert '| tiago_nav, median of the scans at rest | 80/80 | 0 (0) | 0.0071 | 0.0147 |' in ran
    assert '| obstacle_detector, the one scan | 80/80 | 3 (0) | 0.051 | 0.0729 |' in ran
    assert any('6.14× tiago_nav\'s on the same scan, 7.18×' in ln and '5 per call' in ln
               for ln in ran)
    skipped = benchmarks.render_detection({'obstacle_detector': {
        'skipped': True, 'reason': 'obstacle_detector is not installed'}})
    assert skipped[-1] == ('obstacle_detector comparison: skipped '
                           '(obstacle_detector is not installed).')


def test_every_benchmark_json_renders_rows():
    """No rendered table of the page is an empty header (a renderer that does not know its
    JSON's structure)."""
    page = docs.benchmarks_page(ROOT).splitlines()
    for i, line in enumerate(page):
        if line.startswith('|---'):
            assert i + 1 < len(page) and page[i + 1].startswith('| '), \
                'empty table under %r' % page[i - 1]


def test_unknown_benchmark_is_refused():
    with pytest.raises(ValueError):
        benchmarks.commands(['nope'])
    assert len(benchmarks.commands(['lockstep'])) == 5      # idle, loaded, starved, both modes, nav
    assert len(benchmarks.commands(['all'])) == sum(len(r) for _, _, r in benchmarks.BENCHMARKS)


def test_every_benchmark_runs_when_one_misses_its_target(tmp_path, monkeypatch, capsys):
    """A benchmark that exits 1 (a target missed) does not stop the ones after it; the run
    exits with its code and names it."""
    ran = tmp_path / 'ran'
    script = tmp_path / 'bench_x.py'
    script.write_text('import sys\nopen(%r, "a").write(sys.argv[1] + " ")\nsys.exit(int(sys.argv[2]))\n'
                      % str(ran))
    cmds = [[sys.executable, str(script), name, code] for name, code in
            (('first', '0'), ('missed', '1'), ('after', '0'))]
    monkeypatch.setattr(benchmarks, 'commands', lambda names: cmds)
    assert benchmarks.main(['all']) == 1
    assert ran.read_text().split() == ['first', 'missed', 'after']
    err = capsys.readouterr().err
    assert '1 of 3 exited non-zero' in err and 'missed 1: 1' in err, err


def layout_tree():
    """The names of docs/development.md's layout tree, as paths from the repository's root: a
    line's names are separated by one space and end at two spaces (the description); a line
    indented by two more spaces than a folder's line lives in that folder; a line indented to
    the description's column continues the description."""
    with open(os.path.join(ROOT, 'docs', 'development.md')) as f:
        text = f.read()
    block = text.split('## Layout', 1)[1].split('```', 2)[1]
    paths, folders = [], []          # folders: (indent, path) of the enclosing folder lines
    for line in block.splitlines()[1:]:
        indent = len(line) - len(line.lstrip(' '))
        if not line.strip() or indent >= 20:
            continue
        names = line.strip().split('  ')[0].split(' ')
        while folders and folders[-1][0] >= indent:
            folders.pop()
        parent = folders[-1][1] if folders else ''
        for name in names:
            paths.append(os.path.join(parent, name).rstrip('/'))
        if len(names) == 1 and names[0].endswith('/'):
            folders.append((indent, os.path.join(parent, names[0])))
    return paths


def test_the_layout_tree_names_what_exists():
    missing = [p for p in layout_tree() if not os.path.exists(os.path.join(ROOT, p))]
    assert not missing, 'docs/development.md names what does not exist: %s' % missing


def test_the_layout_tree_names_every_folder_and_module():
    """Every entry of the repository's top level (but what .gitignore ignores and .git) and
    every folder and module of the two Python packages is in the tree."""
    import fnmatch
    with open(os.path.join(ROOT, '.gitignore')) as f:
        ignored = [g.strip().strip('/') for g in f if g.strip() and not g.startswith('#')]

    def kept(name):
        return name not in ('.git', '__pycache__', '__init__.py', '__main__.py') \
            and not name.endswith('.pyc') and not any(fnmatch.fnmatch(name, g) for g in ignored)
    wanted = {n for n in os.listdir(ROOT) if kept(n)}
    for package in ('src/tiago_nav', 'src/tiago_nav_tools'):
        wanted |= {'%s/%s' % (package, n) for n in os.listdir(os.path.join(ROOT, package)) if kept(n)}
    missing = sorted(wanted - set(layout_tree()))
    assert not missing, 'missing from the layout tree in docs/development.md: %s' % missing
