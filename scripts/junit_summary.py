#!/usr/bin/env python3
"""Summarises the JUnit XML results of `scripts/flsm test`.

Input: a manifest, one suite per line: "<suite name>\t<exit code>\t<path>", where path is a
gtest XML file, a directory of rostest XML files, or the .log of a check script (one test case
that passed when the script exited with 0). Prints one line per suite and, last, exactly
"N passed, M failed" counted per test case. A suite with no result (it did not build, crashed
before writing one, or timed out) counts as one failed test case, and so does a suite whose
process failed while its XML shows no failure. Exit status 1 if anything failed.
"""

import argparse
import glob
import os
import sys
import xml.etree.ElementTree as ET


def failure_reason(element, limit=400):
    """What a <failure> or <error> says, on one line, so that a log that keeps only the summary
    still says why."""
    text = (element.text or '').strip()
    lines = [l.strip() for l in text.splitlines() if l.strip()]
    if lines and 'Traceback' in text:  # a Python traceback: the assertion is its last line
        reason = lines[-1]
    elif element.get('message'):  # gtest: the message, over a few lines
        reason = element.get('message')
    else:  # rosunit: the message on the first line, the stack below it
        reason = lines[0] if lines else ''
    reason = ' '.join(reason.split())
    return reason if len(reason) <= limit else reason[:limit - 3] + '...'


def testcases(path):
    """(passed, failed, skipped, failure names) of the <testcase>s in one JUnit XML file."""
    root = ET.parse(path).getroot()
    passed, failed, skipped, names = 0, 0, 0, []
    for case in root.iter('testcase'):
        name = '%s.%s' % (case.get('classname', ''), case.get('name', ''))
        bad = case.find('failure')
        bad = bad if bad is not None else case.find('error')
        if bad is not None:
            failed += 1
            reason = failure_reason(bad)
            names.append(name + ('\n      ' + reason if reason else ''))
        elif case.find('skipped') is not None or case.get('status') == 'notrun':
            skipped += 1
        else:
            passed += 1
    return passed, failed, skipped, names


def result_files(path):
    """(per-test files, rostest summary files) for a gtest XML file or a rostest results dir."""
    if os.path.isdir(path):
        # rostest writes rostest-<file>.xml with one case per <test> node (named test<name>,
        # failing when the node failed, crashed or timed out), and each node writes
        # rosunit-<name>.xml (or another name it chose) with its own test cases.
        files = sorted(glob.glob(os.path.join(path, '*.xml')))
        summaries = [f for f in files if os.path.basename(f).startswith('rostest-')]
        return [f for f in files if f not in summaries], summaries
    return ([path] if os.path.isfile(path) else []), []


def failed_test_nodes(summary):
    """Names of the <test> nodes that the rostest summary file reports as failed."""
    root = ET.parse(summary).getroot()
    names = []
    for case in root.iter('testcase'):
        if case.find('failure') is not None or case.find('error') is not None:
            name = case.get('name', '')
            names.append(name[len('test'):] if name.startswith('test') else name)
    return names


def summarise(name, code, path):
    """Returns (passed, failed, report line, failure names)."""
    if path.endswith('.log'):
        # A check script: one test case, its exit code (its output is in the log).
        ok = code == 0
        reason = '' if ok else '   exit code %d%s, see %s' % (
            code, ' (timed out)' if code == 124 else '', path)
        line = '%s %-32s %4d passed, %3d failed%s' % ('OK  ' if ok else 'FAIL', name,
                                                       int(ok), int(not ok), reason)
        return int(ok), int(not ok), line, [] if ok else [name + ' [exit code %d]' % code]
    files, summaries = result_files(path)
    passed = failed = skipped = 0
    names = []
    unreadable = []
    for f in files:
        try:
            p, fl, s, n = testcases(f)
        except ET.ParseError as e:
            unreadable.append('%s (%s)' % (os.path.basename(f), e))
            continue
        passed, failed, skipped = passed + p, failed + fl, skipped + s
        names += n
    # A rostest <test> node that crashed or timed out writes no case of its own: count it from
    # the rostest summary unless its own file already shows a failure.
    notes = []
    for f in summaries:
        try:
            nodes = failed_test_nodes(f)
        except ET.ParseError as e:
            unreadable.append('%s (%s)' % (os.path.basename(f), e))
            continue
        for node in nodes:
            own = os.path.join(os.path.dirname(f), 'rosunit-%s.xml' % node)
            try:
                own_failed = testcases(own)[1] if os.path.isfile(own) else 0
            except ET.ParseError:
                own_failed = 0  # already counted as unreadable
            if own_failed == 0:
                failed += 1
                names.append('%s [test node %s failed without a result of its own]'
                             % (name, node))
                notes.append('test node %s: no result' % node)
    if unreadable:
        failed += 1
        notes.append('unreadable result: ' + ', '.join(unreadable))
    if passed + failed + skipped == 0:
        failed += 1
        reason = 'no result'
        if code == 127:
            reason += ' (test binary was not built)'
        elif code == 124:
            reason += ' (timed out)'
        elif code != 0:
            reason += ' (exit code %d)' % code
        notes.append(reason)
        names.append(name + ' [' + reason + ']')
    elif code != 0 and failed == 0:
        failed += 1
        notes.append('process exited with code %d although its XML shows no failure' % code)
        names.append(name + ' [exit code %d]' % code)
    status = 'OK  ' if failed == 0 else 'FAIL'
    line = '%s %-32s %4d passed, %3d failed' % (status, name, passed, failed)
    if skipped:
        line += ', %d skipped' % skipped
    if notes:
        line += '   ' + '; '.join(notes)
    return passed, failed, line, names


def main():
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument('manifest')
    parser.add_argument('--build-failed', action='store_true',
                        help='the build reported errors: say so (missing suites already count)')
    args = parser.parse_args()

    total_passed = total_failed = 0
    failures = []
    print('\n==================== deformable_flsm test summary ====================')
    with open(args.manifest) as manifest:
        for row in manifest:
            if not row.strip():
                continue
            name, code, path = row.rstrip('\n').split('\t')
            p, f, line, names = summarise(name, int(code), path)
            total_passed += p
            total_failed += f
            failures += names
            print(line)
    if args.build_failed:
        print('NOTE: the build reported errors (see the catkin_make output above); the suites '
              'it could not build are counted as failed.')
        if total_failed == 0:
            total_failed += 1
            failures.append('build [catkin_make failed]')
    if failures:
        print('Failed:')
        for n in failures:
            print('  ' + n)
    print('%d passed, %d failed' % (total_passed, total_failed))
    return 1 if total_failed else 0


if __name__ == '__main__':
    sys.exit(main())
