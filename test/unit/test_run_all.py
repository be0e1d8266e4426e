"""test/run_all.py's summary names each failed test with why it failed, read from the JUnit XML
that pytest and rosunit (rostest's test runner) really write."""
import importlib.util
import os
import subprocess
import sys
import unittest

import pytest


def load(name, path):
    """The module in the file ``path``, imported as ``name``."""
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


run_all = load('run_all', os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))),
                                       'run_all.py'))

FAILING = '''
import unittest
class T(unittest.TestCase):
    def test_far(self):
        self.assertLessEqual(0.61, 0.5, 'a lethal cell at (1.00, 2.00) m is 0.610 m off')
    def test_near(self):
        pass
'''


def test_pytests_failure_is_named_with_its_assertion(tmp_path):
    (tmp_path / 'test_x.py').write_text(FAILING)
    xml = tmp_path / 'out.xml'
    subprocess.call([sys.executable, '-m', 'pytest', '-q', '-p', 'no:cacheprovider',
                     '--junitxml=%s' % xml, str(tmp_path / 'test_x.py')], cwd=str(tmp_path),
                    stdout=subprocess.DEVNULL)
    passed, failed, skipped, names = run_all.junit_counts(str(xml))
    assert (passed, failed, skipped) == (1, 1, 0)
    assert 'test_far' in names[0]
    assert 'a lethal cell at (1.00, 2.00) m is 0.610 m off' in names[0]


@pytest.mark.ros
def test_rosunits_failure_is_named_with_its_assertion_not_its_traceback(tmp_path):
    xmlrunner = pytest.importorskip('rosunit.xmlrunner')
    (tmp_path / 'case_x.py').write_text(FAILING)
    case_x = load('case_x', str(tmp_path / 'case_x.py'))
    xml = tmp_path / 'rosunit-x.xml'
    with open(str(xml), 'w') as f:
        suite = unittest.TestLoader().loadTestsFromTestCase(case_x.T)
        xmlrunner.XMLTestRunner(stream=f).run(suite)
    passed, failed, skipped, names = run_all.junit_counts(str(xml))
    assert (passed, failed) == (1, 1)
    assert 'AssertionError: 0.61 not less than or equal to 0.5 : a lethal cell' in names[0]
    assert 'File "' not in names[0]
