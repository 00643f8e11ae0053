#!/usr/bin/python3
"""Per-thread instruction counts of a consph run, from two callgrind runs with
--separate-threads=yes at K1 and K2 steps (bench/thread_instr.sh), differenced so that the
set-up cancels. Prints, per particle-step: the instructions of each thread; the master's
instructions outside every parallel region (serial: no thread count shortens them), including
the regions that ran on the master alone (an `if` clause below its threshold); and the functions
that only the master ran, the serial work by name.

Under valgrind the threads run one at a time, so how a dynamic schedule shares a loop out says
nothing of a real run: only the serial part and the static loops' shares are meaningful.

usage: thread_instr.py DIR_K1 DIR_K2 K1 K2 PARTICLES
"""
import collections
import os
import re
import subprocess
import sys


def annotate(path, inclusive):
    out = subprocess.run(['callgrind_annotate', '--threshold=100',
                          '--inclusive=' + ('yes' if inclusive else 'no'), path],
                         capture_output=True, text=True, check=True).stdout
    costs, total = collections.Counter(), 0
    for line in out.splitlines():
        m = re.match(r'\s*([\d,]+)\s+(?:\([\d.]+%\)\s+)?(\S.*?)\s+\[', line)
        if m:
            name = m.group(2).split(':', 1)[-1]
            costs[name] += int(m.group(1).replace(',', ''))
        elif 'PROGRAM TOTALS' in line:
            total = int(line.split()[0].replace(',', ''))
    return costs, total


def thread_files(d):
    return [os.path.join(d, f) for f in sorted(os.listdir(d)) if f.startswith('cg.out-')]


def measure(d):
    files = thread_files(d)
    excl = [annotate(f, False)[0] for f in files]
    incl_master, total_master = annotate(files[0], True)
    incl_others = [annotate(f, True)[0] for f in files[1:]]
    outside = total_master - incl_master.get('GOMP_parallel', 0)
    # regions that only the master ran: an `if` clause false, or a team of one
    alone = sum(v for f, v in incl_master.items()
                if '_omp_fn' in f and "'" not in f and all(o.get(f, 0) == 0 for o in incl_others))
    return excl, outside + alone


def main():
    d1, d2 = sys.argv[1], sys.argv[2]
    k1, k2, n = int(sys.argv[3]), int(sys.argv[4]), int(sys.argv[5])
    per = float((k2 - k1) * n)
    (e1, s1), (e2, s2) = measure(d1), measure(d2)
    threads = [collections.Counter({f: b[f] - a.get(f, 0) for f in b}) for a, b in zip(e1, e2)]
    totals = [sum(t.values()) / per for t in threads]
    print('instructions per particle-step, each thread: ' +
          ', '.join('%.1f' % t for t in totals) + '; all: %.1f' % sum(totals))
    print('serial (the master outside every parallel region): %.1f (%.2f %% of all)' %
          ((s2 - s1) / per, 100.0 * (s2 - s1) / per / sum(totals)))
    if len(threads) > 1:
        only = [(f, v / per) for f, v in threads[0].items()
                if all(t.get(f, 0) == 0 for t in threads[1:]) and v / per >= 0.1]
        print('functions only the master ran (per particle-step):')
        for f, v in sorted(only, key=lambda x: -x[1])[:15]:
            print('  %8.1f  %s' % (v, f))
        # the parallel regions' bodies (their own instructions): a static schedule's shares are
        # the real run's; a dynamic one's are valgrind's scheduling, not the real run's
        regions = [(f, [t.get(f, 0) / per for t in threads]) for f in threads[0]
                   if '_omp_fn' in f and sum(t.get(f, 0) for t in threads[1:]) > 0]
        print('parallel regions, each thread (per particle-step), the largest differences:')
        for f, v in sorted(regions, key=lambda x: -(max(x[1]) - min(x[1])))[:8]:
            print('  %s  %s' % (' '.join('%8.1f' % x for x in v), f))


if __name__ == '__main__':
    main()
