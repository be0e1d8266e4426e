#!/usr/bin/env python3
"""Run the unit tests (pytest, no ROS master) and every rostest in test/*.test, then print one
summary line, ``N passed, M failed``; exit non-zero if anything failed or nothing ran.

Called by ``make test`` with the workspace's setup.bash sourced.
"""
import argparse
import glob
import os
import shutil
import subprocess
import sys
import time
import xml.etree.ElementTree as ET

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
RESULTS = os.path.join(ROOT, 'test-results')


def why(element):
    """The gist of a JUnit failure or error element, at most 300 characters, so that the summary
    at the end of a log says what failed as well as where: pytest's ``message`` attribute, or
    rosunit's exception type and the message its text holds before the traceback."""
    text = element.get('message')
    if not text:
        lines = []
        for line in (element.text or '').splitlines():
            if line.lstrip().startswith('File "'):
                break
            lines.append(line.strip())
        text = ' '.join(x for x in [element.get('type', '') + ':'] + lines if x).strip(': ')
    text = ' '.join(text.split()) or 'no message'
    return text if len(text) <= 300 else text[:297] + '...'


def junit_counts(path):
    """(passed, failed, skipped, names of failures with why they failed) of one JUnit XML
    file."""
    passed = failed = skipped = 0
    names = []
    try:
        root = ET.parse(path).getroot()
    except (ET.ParseError, OSError) as e:
        return 0, 1, 0, ['%s: unreadable results (%s)' % (os.path.basename(path), e)]
    for case in root.iter('testcase'):
        bad = case.find('failure')
        bad = bad if bad is not None else case.find('error')
        if bad is not None:
            failed += 1
            names.append('%s.%s (%s)' % (case.get('classname', ''), case.get('name', ''), why(bad)))
        elif case.find('skipped') is not None:
            skipped += 1
        else:
            passed += 1
    return passed, failed, skipped, names


def run_unit(pytest_args):
    xml = os.path.join(RESULTS, 'unit.xml')
    cmd = [sys.executable, '-m', 'pytest', os.path.join(HERE, 'unit'), '-q', '-p', 'no:cacheprovider',
           '--junitxml=' + xml] + pytest_args
    print('== unit tests: %s' % ' '.join(cmd[2:]), flush=True)
    rc = subprocess.call(cmd, cwd=ROOT)
    if not os.path.exists(xml):
        return 0, 1, 0, ['pytest exited %d without results' % rc]
    p, f, s, names = junit_counts(xml)
    if rc not in (0, 5) and f == 0:
        f, names = 1, ['pytest exited %d' % rc]
    return p, f, s, names


def run_rostest(test_file, timeout):
    name = os.path.splitext(os.path.basename(test_file))[0]
    out = os.path.join(RESULTS, 'ros', name)
    shutil.rmtree(out, ignore_errors=True)
    os.makedirs(out)
    cmd = ['rostest', '--results-base-dir', out, 'tiago_nav', os.path.basename(test_file)]
    print('== rostest %s' % os.path.basename(test_file), flush=True)
    t0 = time.monotonic()
    log = os.path.join(RESULTS, 'ros', name + '.log')
    with open(log, 'w') as f:
        try:
            rc = subprocess.call(cmd, stdout=f, stderr=subprocess.STDOUT, timeout=timeout)
        except subprocess.TimeoutExpired:
            rc = 'timeout'
    passed = failed = skipped = 0
    names = []
    for xml in glob.glob(os.path.join(out, '**', 'rosunit-*.xml'), recursive=True):
        p, f_, s, n = junit_counts(xml)
        passed, failed, skipped = passed + p, failed + f_, skipped + s
        names += ['%s: %s' % (name, x) for x in n]
    if rc != 0 and failed == 0:
        failed += 1
        names.append('%s: rostest exited %s (see %s)' % (name, rc, os.path.relpath(log, ROOT)))
    status = 'ok' if rc == 0 and failed == 0 else 'FAILED'
    print('   %s: %d passed, %d failed in %.0f s' % (status, passed, failed, time.monotonic() - t0),
          flush=True)
    if status != 'ok':
        with open(log) as f:
            tail = f.readlines()[-60:]
        sys.stdout.write(''.join('   | ' + line for line in tail))
    return passed, failed, skipped, names


def main():
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument('--unit-only', action='store_true')
    ap.add_argument('--rostest-only', action='store_true')
    ap.add_argument('-k', dest='only', help='run only rostests whose name contains this')
    ap.add_argument('--timeout', type=float, default=600, help='per rostest file [s]')
    args = ap.parse_args()
    os.makedirs(os.path.join(RESULTS, 'ros'), exist_ok=True)
    t0 = time.monotonic()
    totals = [0, 0, 0]
    failures = []
    suites = []
    if not args.rostest_only:
        suites.append(lambda: run_unit([]))
    if not args.unit_only:
        for t in sorted(glob.glob(os.path.join(HERE, '*.test'))):
            if args.only and args.only not in t:
                continue
            suites.append(lambda t=t: run_rostest(t, args.timeout))
    for suite in suites:
        p, f, s, names = suite()
        totals[0] += p
        totals[1] += f
        totals[2] += s
        failures += names
    print('\n== %.0f s' % (time.monotonic() - t0))
    for n in failures:
        print('FAILED %s' % n)
    line = '%d passed, %d failed' % (totals[0], totals[1])
    if totals[2]:
        line += ', %d skipped' % totals[2]
    print(line)
    return 0 if totals[1] == 0 and totals[0] > 0 else 1


if __name__ == '__main__':
    sys.exit(main())
