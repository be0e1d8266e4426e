"""The evaluator's outputs (no ROS): results.csv, summary.md and summary.json (per world group x
profile x candidate: n, successes, rate with its Wilson 95 % interval, medians; infrastructure
errors counted apart and out of the rates; each candidate against the own nodes on the same
scenarios: paired differences with their intervals, McNemar's exact test), junit.xml,
plots/*.png and manifest.json."""
import csv
import json
import os
import platform
import socket
import subprocess
import time
from xml.sax.saxutils import escape, quoteattr

from tiago_nav_tools.evaluate import metrics as M
from tiago_nav_tools.evaluate import timing
from tiago_nav_tools.evaluate.run import INFRA, write_json
from tiago_nav_tools.evaluate.supervisor import END_WAIT

COLUMNS = ('run_id', 'outcome', 'reason', 'world', 'world_group', 'profile', 'use_corridor_law',
           'seed', 'candidate', 'goal_x', 'goal_y', 'goal_yaw_deg', 'success', 'time_s', 'wall_s',
           'path_length_m', 'shortest_m', 'spl', 'barn_score', 'collisions', 'min_clearance_m',
           'recall', 'false_positives', 'rms_error', 'max_error', 'in_view', 'found_count',
           'glimpsed', 'missed', 'matched_glimpsed',
           'loc_error_p95_m', 'loc_error_p95_deg', 'closest_walker_m', 'waiting_s',
           'walkers_reported', 'walkers_static', 'ghost_age_s', 'sim_wall_ratio', 'cpu_s',
           'attempt')
MEDIANS = ('time_s', 'wall_s', 'path_length_m', 'spl', 'barn_score', 'min_clearance_m',
           'rms_error', 'loc_error_p95_m', 'sim_wall_ratio', 'cpu_s')
PAIRED = ('time_s', 'spl', 'barn_score', 'min_clearance_m', 'rms_error')


def is_infra(r):
    return r.get('outcome') in INFRA or r.get('outcome') in (None, 'NO_RESULT')


def row(r):
    g = r.get('goal') or [None] * 3
    d = {k: r.get(k) for k in COLUMNS}
    d.update(goal_x=g[0], goal_y=g[1], goal_yaw_deg=g[2], found_count=r.get('found') and len(r['found']),
             success=None if is_infra(r) else M.success(r.get('outcome')))
    return d


def write_csv(path, results):
    with open(path + '.tmp', 'w', newline='') as f:
        w = csv.DictWriter(f, fieldnames=COLUMNS)
        w.writeheader()
        for r in results:
            w.writerow({k: ('%.6g' % v if isinstance(v, float) else v) for k, v in row(r).items()})
    os.replace(path + '.tmp', path)


def group_key(r):
    return (r.get('world_group') or r.get('world'), r.get('profile'), r.get('candidate'))


def summarise(results):
    """Per group: counts, the success rate with its Wilson interval (infrastructure errors
    out), outcome counts, medians; plus the paired comparisons of each candidate with 'own'."""
    groups = {}
    for r in results:
        groups.setdefault(group_key(r), []).append(r)
    out = []
    for (world, profile, cand), rs in sorted(groups.items(), key=lambda kv: tuple(map(str, kv[0]))):
        valid = [r for r in rs if not is_infra(r)]
        k = sum(M.success(r['outcome']) for r in valid)
        lo, hi = M.wilson(k, len(valid))
        outcomes = {}
        for r in rs:
            outcomes[r.get('outcome') or 'NO_RESULT'] = outcomes.get(r.get('outcome') or 'NO_RESULT', 0) + 1
        out.append({'world': world, 'profile': profile, 'candidate': cand, 'runs': len(rs),
                    'n': len(valid), 'successes': k, 'rate': k / len(valid) if valid else None,
                    'wilson_low': lo, 'wilson_high': hi,
                    'infra_errors': len(rs) - len(valid), 'outcomes': outcomes,
                    'collisions': sum(r.get('collisions') or 0 for r in valid),
                    'medians': {m: M.median([r.get(m) for r in valid]) for m in MEDIANS}})
    return out


def compare(results):
    """Each candidate against 'own' over the scenarios both ran without infrastructure errors."""
    own = {r['pair']: r for r in results if r.get('candidate') == 'own' and not is_infra(r)}
    cands = sorted({r.get('candidate') for r in results} - {'own', None})
    out = []
    for c in cands:
        pairs = [(r, own[r['pair']]) for r in results
                 if r.get('candidate') == c and not is_infra(r) and r.get('pair') in own]
        b = sum(1 for x, y in pairs if M.success(x['outcome']) and not M.success(y['outcome']))
        cc = sum(1 for x, y in pairs if not M.success(x['outcome']) and M.success(y['outcome']))
        d = {'candidate': c, 'pairs': len(pairs),
             'success_candidate': sum(M.success(x['outcome']) for x, _ in pairs),
             'success_own': sum(M.success(y['outcome']) for _, y in pairs),
             'only_candidate': b, 'only_own': cc, 'mcnemar_p': M.mcnemar_exact(b, cc),
             'success_difference': M.paired_difference([M.success(x['outcome']) for x, _ in pairs],
                                                       [M.success(y['outcome']) for _, y in pairs])}
        for m in PAIRED:
            d[m + '_difference'] = M.paired_difference([x.get(m) for x, _ in pairs],
                                                       [y.get(m) for _, y in pairs])
        out.append(d)
    return out


def _f(v, fmt='%.3g'):
    return '-' if v is None else fmt % v


def markdown(summary, comparison, results, meta):
    infra = [r for r in results if is_infra(r)]
    valid = [r for r in results if not is_infra(r)]
    k = sum(M.success(r['outcome']) for r in valid)
    lo, hi = M.wilson(k, len(valid))
    lines = ['# Evaluation summary', '',
             '%d runs: %d judged, %d succeeded (%.1f %%, Wilson 95 %% %.1f-%.1f %%), %d infrastructure '
             'errors (out of the rates). Wall time %.0f s, %.2f missions per minute.'
             % (len(results), len(valid), k, 100.0 * k / len(valid) if valid else 0, 100 * lo, 100 * hi,
                len(infra), meta['wall_s'], meta['missions_per_minute'] or 0), '',
             '| world | profile | candidate | n | successes | rate [95 % CI] | infra | outcomes | '
             'median time [s] | median SPL | median BARN | min clearance [m] | median RMS [m] | '
             'loc p95 [m] | sim/wall | CPU [s] |',
             '|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|']
    for g in summary:
        md = g['medians']
        lines.append('| %s | %s | %s | %d | %d | %s [%.2f, %.2f] | %d | %s | %s | %s | %s | %s | %s | %s | %s | %s |' % (
            g['world'], g['profile'], g['candidate'], g['n'], g['successes'], _f(g['rate'], '%.2f'),
            g['wilson_low'], g['wilson_high'], g['infra_errors'],
            ', '.join('%s %d' % kv for kv in sorted(g['outcomes'].items())),
            _f(md['time_s'], '%.1f'), _f(md['spl'], '%.2f'), _f(md['barn_score'], '%.3f'),
            _f(md['min_clearance_m'], '%.3f'), _f(md['rms_error'], '%.3f'),
            _f(md['loc_error_p95_m'], '%.3f'), _f(md['sim_wall_ratio'], '%.1f'), _f(md['cpu_s'], '%.0f')))
    if comparison:
        lines += ['', '## Candidates against the own nodes (paired, same scenarios)', '',
                  '| candidate | pairs | successes cand./own | only cand. | only own | McNemar exact p | '
                  'success diff [95 % CI] | time diff [s] [95 % CI] | SPL diff [95 % CI] |',
                  '|---|---|---|---|---|---|---|---|---|']
        for c in comparison:
            def ci(d):
                return '%s [%s, %s] (n=%d)' % (_f(d['mean']), _f(d['low']), _f(d['high']), d['n'])
            lines.append('| %s | %d | %d/%d | %d | %d | %.3g | %s | %s | %s |' % (
                c['candidate'], c['pairs'], c['success_candidate'], c['success_own'],
                c['only_candidate'], c['only_own'], c['mcnemar_p'], ci(c['success_difference']),
                ci(c['time_s_difference']), ci(c['spl_difference'])))
    if infra:
        lines += ['', '## Infrastructure errors (retried once; not in the rates)', '']
        lines += ['- `%s` %s: %s' % (r['run_id'], r.get('outcome'), r.get('reason', '')) for r in infra]
    short = [r for r in valid if r.get('end_missing')]
    if short:
        lines += ['', '## Runs whose last records did not all come (judged on what came)', '']
        lines += ['- `%s`: no %s within %g s of the result' % (
            r['run_id'], ', '.join(r['end_missing']), END_WAIT) for r in short]
    lines[3:3] = divergence_lines(results)       # (after the headline)
    lines += isolation_lines(meta)
    lines += detection_lines(valid)
    lines += shape_lines(valid)
    lines += people_lines(valid)
    bad = [r for r in valid if r['outcome'] != 'succeeded']
    if bad:
        lines += ['', '## Runs that did not succeed', '']
        lines += ['- `%s` %s B=%s law=%s seed=%s %s: **%s** %s' % (
            r['run_id'], r['world'], r.get('goal'), r.get('use_corridor_law'), r.get('seed'),
            r['candidate'], r['outcome'], r.get('reason', '')) for r in bad]
    lines += time_lines(results, meta)
    return '\n'.join(lines) + '\n'


def detection_totals(results):
    """Per profile, over the judged runs that reported obstacles (a result with
    ``detection_view``): obstacles ``in_view`` and ``glimpsed`` (:mod:`tiago_nav_tools.evaluate.inview`),
    ``found`` centres, ``missed`` (in view, not found), ``false_positives``, ``matched`` and
    ``matched_glimpsed``, ``bounded`` and ``bounded_outside`` (matched centres not fixed,
    judged by their reported bound, and those outside it), and the centre error [m] of every
    matched obstacle, glimpsed ones too (``rms_error``, ``max_error``, and the same over the
    glimpsed ones alone)."""
    out = {}
    for r in results:
        view = r.get('detection_view')
        if view is None:
            continue
        t = out.setdefault(r.get('profile'), {'runs': 0, 'in_view': 0, 'glimpsed': 0, 'found': 0,
                                              'missed': 0, 'false_positives': 0, 'matched': 0,
                                              'matched_glimpsed': 0, 'bounded': 0,
                                              'bounded_outside': 0, '_e': [], '_g': []})
        t['runs'] += 1
        for k in ('in_view', 'glimpsed', 'missed', 'false_positives', 'matched_glimpsed',
                  'bounded', 'bounded_outside'):
            t[k] += int(r.get(k) or 0)
        t['found'] += len(r.get('found') or [])
        t['matched'] += int(r.get('matched') or 0)
        for o in view:
            if o.get('error') is not None:
                t['_e'].append(o['error'])
                if not o['in_view']:
                    t['_g'].append(o['error'])
    for t in out.values():
        e, g = t.pop('_e'), t.pop('_g')
        t['rms_error'] = (sum(x * x for x in e) / len(e)) ** 0.5 if e else None
        t['max_error'] = max(e) if e else None
        t['rms_error_glimpsed'] = (sum(x * x for x in g) / len(g)) ** 0.5 if g else None
        t['max_error_glimpsed'] = max(g) if g else None
    return out


def detection_lines(results):
    """summary.md's detection section: :func:`detection_totals` per profile."""
    tot = detection_totals(results)
    if not tot:
        return []
    lines = ['', '## Detection (runs that reached pose B)', '',
             'In view: at least %d usable beams of the noise-free cast hit the obstacle; glimpsed: '
             'fewer (docs/evaluation.md). A glimpsed obstacle may go unreported; a centre reported '
             'for it is scored like any other. Not fixed: centres reported with center_fixed '
             'false, judged by their reported bound (the 99.9 %% ellipse) instead of the '
             'tolerance.' % _min_beams(), '',
             '| profile | runs | in view | glimpsed | found | missed | false positives | '
             'matched in view | matched glimpsed | not fixed (outside their bound) | '
             'centre RMS [m] | centre max [m] | glimpsed RMS [m] | glimpsed max [m] |',
             '|---|---|---|---|---|---|---|---|---|---|---|---|---|---|']
    for prof, t in sorted(tot.items(), key=lambda kv: str(kv[0])):
        lines.append('| %s | %d | %d | %d | %d | %d | %d | %d | %d | %d (%d) | %s | %s | %s | %s |' % (
            prof, t['runs'], t['in_view'], t['glimpsed'], t['found'], t['missed'],
            t['false_positives'], t['matched'], t['matched_glimpsed'], t['bounded'],
            t['bounded_outside'],
            _f(t['rms_error'], '%.4f'), _f(t['max_error'], '%.4f'),
            _f(t['rms_error_glimpsed'], '%.4f'), _f(t['max_error_glimpsed'], '%.4f')))
    return lines


def people_summary(results):
    """summary.json's ``people``: per profile and candidate, over the judged runs in worlds with
    walkers (a result with ``closest_walker_m``): ``runs``, ``collisions``, ``closest_walker_m``
    (the least gap of the base's body to a walker's legs over them), ``runs_under_gap`` (runs
    nearer than :data:`metrics.WALKER_GAP`), ``waiting_s_mean`` and ``waiting_s_max``
    (standing still away from pose B), ``walkers_reported`` (reports of a walker as a person:
    moving or legs) and ``walkers_static`` (reports of a walker as a static obstacle), with
    ``runs_walker_static``; ``ghost_age_s_max`` (the oldest ghost in the navigation's
    published costmaps, :mod:`~tiago_nav_tools.evaluate.ghosts`), ``runs_ghost_over`` (runs
    with one older than :data:`metrics.GHOST_AGE`) and ``runs_no_costmap`` (runs whose
    navigation published none)."""
    groups = {}
    for r in results:
        if 'closest_walker_m' in r:
            groups.setdefault((str(r.get('profile')), str(r.get('candidate'))), []).append(r)
    out = []
    for (profile, cand), rs in sorted(groups.items()):
        gaps = [r['closest_walker_m'] for r in rs if r.get('closest_walker_m') is not None]
        waits = [r['waiting_s'] for r in rs if r.get('waiting_s') is not None]
        ghosts = [r['ghost_age_s'] for r in rs if r.get('ghost_age_s') is not None]
        out.append({'profile': profile, 'candidate': cand, 'runs': len(rs),
                    'collisions': sum(int(r.get('collisions') or 0) for r in rs),
                    'closest_walker_m': min(gaps) if gaps else None,
                    'runs_under_gap': sum(1 for g in gaps if g < M.WALKER_GAP),
                    'waiting_s_mean': sum(waits) / len(waits) if waits else None,
                    'waiting_s_max': max(waits) if waits else None,
                    'walkers_reported': sum(int(r.get('walkers_reported') or 0) for r in rs),
                    'walkers_static': sum(int(r.get('walkers_static') or 0) for r in rs),
                    'runs_walker_static': sum(1 for r in rs if r.get('walkers_static')),
                    'ghost_age_s_max': max(ghosts) if ghosts else None,
                    'runs_ghost_over': sum(1 for g in ghosts if g > M.GHOST_AGE),
                    'runs_no_costmap': len(rs) - len(ghosts)})
    return out


def people_lines(results):
    """summary.md's people section: :func:`people_summary`."""
    rows = people_summary(results)
    if not rows:
        return []
    lines = ['', '## People (runs in worlds with walkers)', '',
             'Closest: the least gap between the base\'s body and a walker\'s legs over the mission '
             '(bar: at least %g m); waiting: time the base stood still away from pose B; walkers '
             'reported: obstacles reported where a walker was, as a person (moving or legs) or as '
             'a static obstacle (a detection failure); oldest ghost: a mark in the navigation\'s '
             'published costmap where nothing is, after a scan saw its place free (bar: %g s; '
             'runs without a costmap in brackets). docs/evaluation.md#people.'
             % (M.WALKER_GAP, M.GHOST_AGE), '',
             '| profile | candidate | runs | collisions | closest [m] | runs under %g m | '
             'waiting mean [s] | waiting max [s] | walkers reported as persons | as static '
             '(runs) | oldest ghost [s] | runs over %g s |' % (M.WALKER_GAP, M.GHOST_AGE),
             '|---|---|---|---|---|---|---|---|---|---|---|---|']
    for g in rows:
        lines.append('| %s | %s | %d | %d | %s | %d | %s | %s | %d | %d (%d) | %s%s | %d |' % (
            g['profile'], g['candidate'], g['runs'], g['collisions'],
            _f(g['closest_walker_m'], '%.3f'), g['runs_under_gap'], _f(g['waiting_s_mean'], '%.1f'),
            _f(g['waiting_s_max'], '%.1f'), g['walkers_reported'], g['walkers_static'],
            g['runs_walker_static'], _f(g['ghost_age_s_max'], '%.1f'),
            ' (%d)' % g['runs_no_costmap'] if g['runs_no_costmap'] else '', g['runs_ghost_over']))
    return lines


def shape_lines(results):
    """summary.md's shapes section: :func:`tiago_nav_tools.evaluate.shapes.summarise` per
    profile, candidate and true shape, the issue's targets beside the figures."""
    from tiago_nav_tools.evaluate import shapes as S
    groups = S.summarise(results)
    if not groups:
        return []
    lines = ['', '## Shapes (runs that reached pose B)', '',
             'By true shape, each movable obstacle in view or matched at pose B (docs/evaluation.md#'
             'shapes): found = in view and matched; label agrees: cylinder - circle, box - '
             'rectangle, table and chair - legs; errors over the matched ones, median / p95 '
             '(nearest rank), n the obstacles whose value is observed. The targets (centre <= '
             '%.0f cm, orientation <= %.0f deg) apply to boxes seen on two faces whole and to '
             'tables and chairs seen on three legs or more.' % (100 * S.TARGET_CENTRE,
                                                                 S.TARGET_ORIENTATION), '',
             '| profile | candidate | shape | in view | found | label agrees | '
             'centre median / p95 [cm] | extent median / p95 [cm] (n) | '
             'orientation median / p95 [deg] (n) | target applies | centre p95 there [cm] '
             '(target) | orientation p95 there [deg] (target) |',
             '|---|---|---|---|---|---|---|---|---|---|---|---|']

    def cm(v):
        return _f(None if v is None else 100.0 * v, '%.1f')

    def pct(v):
        return _f(None if v is None else 100.0 * v, '%.0f %%')

    for g in groups:
        target = g['shape'] in S.TARGET_SHAPES
        lines.append('| %s | %s | %s | %d | %d (%s) | %d/%d (%s) | %s / %s | %s / %s (%d) | '
                     '%s / %s (%d) | %s | %s | %s |' % (
                         g['profile'], g['candidate'], g['shape'], g['in_view'], g['found'],
                         pct(g['found_share']), g['label_agrees'], g['matched'],
                         pct(g['label_share']),
                         cm(g['centre_median']), cm(g['centre_p95']),
                         cm(g['extent_median']), cm(g['extent_p95']), g['extent_n'],
                         _f(g['orientation_median'], '%.1f'), _f(g['orientation_p95'], '%.1f'),
                         g['orientation_n'],
                         g['target_n'] if target else '-',
                         '%s (<= %.0f)' % (cm(g['target_centre_p95_m']), 100 * S.TARGET_CENTRE)
                         if target else '-',
                         '%s (<= %.0f)' % (_f(g['target_orientation_p95_deg'], '%.1f'),
                                           S.TARGET_ORIENTATION) if target else '-'))
    return lines


def _min_beams():
    from tiago_nav_tools.evaluate.inview import MIN_BEAMS
    return MIN_BEAMS


def shape_summary(results):
    """summary.json's ``shapes``: :func:`tiago_nav_tools.evaluate.shapes.summarise`."""
    from tiago_nav_tools.evaluate import shapes as S
    return S.summarise(results)


def isolations(results):
    """``{isolation: runs}`` over the results that ran (``netns``, ``loopback``)."""
    out = {}
    for r in results:
        if r.get('isolation'):
            out[r['isolation']] = out.get(r['isolation'], 0) + 1
    return out


def stacks(results):
    """How the runs of a ``--warm`` batch got their stack: ``{'fresh': runs on a stack started
    for them, 'reset': runs after a reset, 'reset_failed': runs rerun on a fresh stack after a
    failed reset, 'checked': reset runs that ``--verify-reset`` ran again on a fresh stack,
    'verified': those equal to it, 'diverged': those that differ (their ids in
    'diverged_runs'), 'verify_errors': those whose fresh run failed, 'startup_fresh_s',
    'startup_reset_s': the median start-up wall time of each}``; None when no run was warm."""
    warm = [r for r in results if r.get('stack')]
    if not warm:
        return None

    def startup(kind):
        return M.median([((r.get('phases') or {}).get('startup') or {}).get('wall_s')
                         for r in warm if r['stack'] == kind and isinstance(r.get('phases'), dict)])
    return {'fresh': sum(r['stack'] != 'reset' for r in warm),
            'reset': sum(r['stack'] == 'reset' for r in warm),
            'reset_failed': sum(bool(r.get('reset_failed')) for r in warm),
            'checked': sum('verified' in r for r in warm),
            'verified': sum(r.get('verified') is True for r in warm),
            'diverged': sum(bool(r.get('diverged')) for r in warm),
            'diverged_runs': [r['run_id'] for r in warm if r.get('diverged')],
            'verify_errors': sum(bool(r.get('verify_error')) for r in warm),
            'startup_fresh_s': startup('fresh'), 'startup_reset_s': startup('reset')}


def isolation_lines(meta):
    iso = meta.get('isolation') or {}
    if not iso:
        return []
    warm = meta.get('stacks')
    about = {'netns': 'each run in a network namespace of its own, only loopback up',
             'loopback': 'the host network, loopback addresses, one port per worker'}
    if warm:
        about = {'netns': 'each stack (master and nodes) in a network namespace of its own, only '
                          'loopback up; a warm stack\'s rows share its namespace, no two stacks '
                          'share one',
                 'loopback': 'the host network, loopback addresses, one port per worker'}
    return ['', 'Isolation: %s.' % '; '.join(
        '%s (%s) for %d run%s' % (k, about.get(k, '?'), n, '' if n == 1 else 's') for k, n in sorted(iso.items()))]


def stack_lines(meta):
    w = meta.get('stacks')
    if not w:
        return []
    return ['', 'Warm stacks: %d run%s after a reset (median start-up %s s), %d on a stack started '
            'for them (median start-up %s s); %d rerun on a fresh stack after a failed reset; %d '
            'reset run%s checked against a fresh stack: %d equal, %d diverged, %d not verified '
            '(the fresh run failed).' % (
                w['reset'], '' if w['reset'] == 1 else 's', _f(w['startup_reset_s'], '%.2f'),
                w['fresh'], _f(w['startup_fresh_s'], '%.2f'), w['reset_failed'], w['checked'],
                '' if w['checked'] == 1 else 's', w['verified'], w['diverged'],
                w['verify_errors'])]


def divergence_lines(results):
    """summary.md's list of the reset runs that differ from a fresh stack's run of their row
    (``--verify-reset``), and of those that could not be checked; nothing when there are none."""
    bad = [r for r in results if r.get('diverged')]
    lost = [r for r in results if r.get('verify_error')]
    if not bad and not lost:
        return []
    lines = ['', '## Resets that diverged from a fresh stack (exit status 3)', '',
             '%d reset run%s differ%s from a fresh stack\'s run of the same row, %d could not be '
             'checked. A '
             'diverged row counts with the fresh run\'s outcome and figures (the reference); the '
             'warm run is in `runs/ID/reset_result.json`.' % (
                 len(bad), '' if len(bad) == 1 else 's', 's' if len(bad) == 1 else '', len(lost)), '']
    lines += ['- `%s`: after the reset %s, fresh %s; differs in %s' % (
        r['run_id'], (r.get('reset_result') or {}).get('outcome'), r.get('outcome'),
        ', '.join(r['diverged'])) for r in bad]
    lines += ['- `%s`: not verified: %s' % (r['run_id'], r['verify_error']) for r in lost]
    return lines


def time_lines(results, meta):
    """summary.md's "Where the time goes": the batch's phases (:mod:`timing`), then per run."""
    t = meta.get('time')
    if not t:
        return []
    lines = ['', '## Where the time goes', '',
             'Missions took %s of the batch\'s worker time (%.0f s: wall time x workers%s).'
             % ('-' if t['mission_share'] is None else '%.1f %%' % (100 * t['mission_share']),
                t['worker_time_s'], '' if meta.get('workers_effective') else '; the runs\' summed '
                'wall time when the worker count is unknown'), '',
             '| phase | wall [s] | share of run wall | median wall [s] | CPU [s] | median CPU [s] |',
             '|---|---|---|---|---|---|']
    lines[4:4] = stack_lines(meta)        # (after the missions' share)
    for k in timing.PHASES:
        p = t['phases'][k]
        lines.append('| %s | %.1f | %s | %s | %s | %s |' % (
            k, p['wall_s'], '-' if p['wall_share'] is None else '%.1f %%' % (100 * p['wall_share']),
            _f(p['median_wall_s'], '%.2f'), _f(p['cpu_s'], '%.1f'), _f(p['median_cpu_s'], '%.2f')))
    lines += ['', '### Per run (wall / CPU seconds)', '',
              '| run | outcome | start-up | mission | judging | teardown | total |',
              '|---|---|---|---|---|---|---|']
    for r in results:
        ph = r.get('phases')
        if not isinstance(ph, dict):
            continue

        def cell(k):
            p = ph.get(k) or {}
            return '%s / %s' % (_f(p.get('wall_s'), '%.2f'), _f(p.get('cpu_s'), '%.2f'))
        total_w = sum((ph.get(k) or {}).get('wall_s') or 0.0 for k in timing.PHASES)
        cpus = [(ph.get(k) or {}).get('cpu_s') for k in timing.PHASES]
        total_c = None if any(c is None for c in cpus) else sum(cpus)
        lines.append('| `%s` | %s | %s | %s | %s | %s | %.2f / %s |' % (
            r['run_id'], r.get('outcome'), cell('startup'), cell('mission'), cell('judging'),
            cell('teardown'), total_w, _f(total_c, '%.2f')))
    return lines


def junit(results):
    cases = []
    fails = 0
    for r in results:
        name = '%s %s %s seed %s %s' % (r.get('world'), r.get('profile'), r.get('candidate'),
                                        r.get('seed'), r['run_id'])
        t = r.get('run_wall_s') or 0.0
        body = ''
        if r.get('outcome') != 'succeeded':
            fails += 1
            text = '%s: %s' % (r.get('outcome'), r.get('reason', ''))
            tag = 'error' if is_infra(r) else 'failure'
            body = '<%s message=%s>%s</%s>' % (tag, quoteattr(text), escape(text), tag)
        cases.append('  <testcase classname="evaluate.%s" name=%s time="%.3f">%s</testcase>'
                     % (r.get('candidate'), quoteattr(name), t, body))
    errors = sum(1 for r in results if is_infra(r))
    return ('<?xml version="1.0" encoding="utf-8"?>\n<testsuite name="evaluate" tests="%d" '
            'failures="%d" errors="%d">\n%s\n</testsuite>\n'
            % (len(results), fails - errors, errors, '\n'.join(cases)))


def plots(out, results, runs):
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    pdir = os.path.join(out, 'plots')
    os.makedirs(pdir, exist_ok=True)
    valid = [r for r in results if not is_infra(r)]
    params = [('world_group', 'world'), ('profile', 'profile'), ('use_corridor_law', 'corridor law'),
              ('candidate', 'candidate')]
    fig, axes = plt.subplots(1, len(params), figsize=(4 * len(params), 4), squeeze=False)
    for ax, (key, label) in zip(axes[0], params):
        vals = sorted({str(r.get(key)) for r in valid})
        rates, lo, hi = [], [], []
        for v in vals:
            rs = [r for r in valid if str(r.get(key)) == v]
            k = sum(M.success(r['outcome']) for r in rs)
            a, b = M.wilson(k, len(rs))
            rates.append(k / len(rs))
            lo.append(max(0.0, k / len(rs) - a))       # (rounding: b may fall 1e-16 short of 1)
            hi.append(max(0.0, b - k / len(rs)))
        ax.bar(range(len(vals)), rates, yerr=[lo, hi], capsize=4, color='tab:green')
        ax.set_xticks(range(len(vals)))
        ax.set_xticklabels(vals, rotation=30, ha='right', fontsize=7)
        ax.set_ylim(0, 1.05)
        ax.set_title('success by %s (Wilson 95 %%)' % label, fontsize=9)
    fig.tight_layout()
    fig.savefig(os.path.join(pdir, 'success.png'), dpi=100)
    plt.close(fig)
    groups = {}
    for r in valid:
        if r.get('time_s') is not None:
            groups.setdefault('%s\n%s\n%s' % group_key(r), []).append(r['time_s'])
    if groups:
        fig, ax = plt.subplots(figsize=(max(6, 1.6 * len(groups)), 4))
        ax.boxplot(list(groups.values()))
        ax.set_xticks(range(1, len(groups) + 1))
        ax.set_xticklabels(list(groups), fontsize=7)
        ax.set_ylabel('mission time [s simulated]')
        ax.set_title('time distributions')
        fig.tight_layout()
        fig.savefig(os.path.join(pdir, 'time.png'), dpi=100)
        plt.close(fig)
    # the worst runs: failures first, then the lowest SPL
    worst = sorted([r for r in valid if r.get('path')],
                   key=lambda r: (M.success(r['outcome']), r.get('spl') or 0.0))[:4]
    from tiago_nav.sim.world import load_world
    from tiago_nav_tools.evaluate.matching import plot_run
    from tiago_nav_tools.evaluate.run import world_path
    specs = {s['id']: s for s in runs}
    import math
    for i, r in enumerate(worst):
        s = specs.get(r['run_id'])
        if s is None:
            continue
        world = load_world(world_path(s, out))
        from tiago_nav.sim.raster import rasterise_world
        g = r['goal']
        plot_run(os.path.join(pdir, 'worst_%d_%s.png' % (i + 1, r['run_id'])), rasterise_world(world),
                 world, r['path'], None,
                 [(0, t[0], t[1], t[2]) for t in r.get('detection_truth') or []],
                 [(o[0], o[1]) for o in r.get('found') or []], goal=(g[0], g[1], math.radians(g[2])),
                 title='%s: %s %s (%s)' % (r['run_id'], r['world'], r['outcome'], (r.get('reason') or '')[:60]))


def write_all(out, runs, results, wall_s, workers=None, scheduler=None):
    """Write every output; return the summary's first lines."""
    judged = [r for r in results if r.get('run_wall_s')]
    meta = {'wall_s': wall_s, 'runs': len(results), 'workers': workers, 'scheduler': scheduler,
            'missions_per_minute': len(judged) / wall_s * 60.0 if judged and wall_s > 0 else None}
    # a local cluster has workers or the number of cores; a scheduler's count is not known here
    meta['workers_effective'] = None if scheduler else (workers or os.cpu_count() or 1)
    meta['isolation'] = isolations(results)
    meta['stacks'] = stacks(results)
    meta['time'] = timing.batch(results, wall_s, meta['workers_effective'])
    write_csv(os.path.join(out, 'results.csv'), results)
    summary = summarise(results)
    comparison = compare(results)
    write_json(os.path.join(out, 'summary.json'), {'schema': 1, 'meta': meta, 'groups': summary,
                                                   'comparison': comparison,
                                                   'detection': detection_totals(
                                                       [r for r in results if not is_infra(r)]),
                                                   'shapes': shape_summary(
                                                       [r for r in results if not is_infra(r)]),
                                                   'people': people_summary(
                                                       [r for r in results if not is_infra(r)])})
    text = markdown(summary, comparison, results, meta)
    with open(os.path.join(out, 'summary.md.tmp'), 'w') as f:
        f.write(text)
    os.replace(os.path.join(out, 'summary.md.tmp'), os.path.join(out, 'summary.md'))
    with open(os.path.join(out, 'junit.xml.tmp'), 'w') as f:
        f.write(junit(results))
    os.replace(os.path.join(out, 'junit.xml.tmp'), os.path.join(out, 'junit.xml'))
    try:
        plots(out, results, runs)
    except Exception as e:      # noqa: BLE001  (plots are a convenience; the figures are written)
        print('evaluate: plots failed: %s' % e)
    return '\n'.join(text.splitlines()[:3])


def write_manifest(out, suite_path, data, runs, args):
    from tiago_nav_tools.evaluate.suite import suite_hash
    root = os.path.dirname(os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__)))))

    def git(*a):
        try:
            return subprocess.check_output(['git', '-C', root] + list(a), text=True,
                                           stderr=subprocess.DEVNULL).strip()
        except (OSError, subprocess.CalledProcessError):
            return None
    versions = {}
    for mod in ('numpy', 'scipy', 'pybullet', 'dask', 'distributed', 'matplotlib', 'yaml'):
        try:
            versions[mod] = getattr(__import__(mod), '__version__', None)
        except Exception:       # noqa: BLE001
            versions[mod] = None
    write_json(os.path.join(out, 'manifest.json'), {
        'schema': 1, 'git_commit': git('rev-parse', 'HEAD'), 'git_dirty': bool(git('status', '--porcelain')),
        'suite': os.path.abspath(suite_path), 'suite_hash': suite_hash(data), 'runs': len(runs),
        'run_ids': [r['id'] for r in runs], 'args': {k: v for k, v in args.items()},
        'host': socket.gethostname(), 'platform': platform.platform(),
        'python': platform.python_version(), 'versions': versions,
        'ros_distro': os.environ.get('ROS_DISTRO'), 'started': time.strftime('%Y-%m-%dT%H:%M:%SZ', time.gmtime())})
