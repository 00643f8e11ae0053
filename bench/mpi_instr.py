#!/usr/bin/python3
"""Instructions per owned particle-step of a decomposed run, by kind of work (bench/mpi_instr.sh).

    mpi_instr.py N STEPS LABEL=DIR_SHORT:DIR_LONG [LABEL=...]

Each DIR holds one cachegrind file per rank (cg.PID) of the same run with STEPS fewer steps
(DIR_SHORT) or more (DIR_LONG); their difference cancels the set-up and the last output. Every
rank's counts are summed, so the numbers are the whole job's instructions per particle-step of
an N-particle run (the serial run's, plus what the ranks add), and the largest rank's share
times the ranks (the step waits for it) in the row "slowest rank x K", and again without the
MPI library (its polling while a rank waits follows the machine's load). Functions are put in
kinds by name (the build has no line information); libc's copies and fills stay apart."""
import collections
import glob
import re
import sys

KINDS = [
    ('pair work (pass visits, kernel, gathers)',
     r'^(first_|coupled_|gather_avx|gather4|group_|ipst_group|ipst_volume_group|'
     r'consph_kernel_eval|ipst_visit|nlist_pass_run|nlist_chain|visit_|'
     r'density_visit|nnps_gather|consph_nnps_gather|consph_pass_run|kit_|rhs_|pass_)'),
    ('particle loops (schemes, integrator: halo included)',
     r'^(rates|set_fields|reg_|step_|integ_|sum_|consph_sum|regularise|ipst_)'),
    ('search build and serial re-sort',
     r'^(consph_nnps_|nnps_|nlist_|index_block|cache_block|consph_particles_permute|'
     r'sys_carry|permute_)'),
    ('halo refresh', r'^(refresh|column_changed|gather_column|halo_|list_|__memcmp)'),
    ('migration and install',
     r'^(migrate|install|in_halo|cover|cut_|held_cmp|cell_of|owner_of|copy_particle|'
     r'particles_for|particles_like|unpack|msort|qsort|sort_held|copy_runs|runs_of)'),
    ('rank 0 gathers, checks over ranks', r'^(par_|solver_|diag_|step_close|__sincos)'),
    ('MPI library (waiting included)', r'^(opal_|mca_|ompi_|PMPI_|MPI_|pmix|PMIx|\?\?\?|event_)'),
    ('libc copies and fills (and copy_doubles)',
     r'^(__memcpy|__memmove|__memset|__mempcpy|copy_doubles)'),
    ('malloc/free', r'^(_int_|malloc|free|realloc|calloc|unlink_chunk|consph_calloc|cfree)'),
]


def load(d):
    ranks = []
    for f in sorted(glob.glob(d + '/cg.*')):
        fn = collections.Counter()
        cur = None
        for line in open(f, errors='replace'):
            if line.startswith('fn='):
                cur = line[3:].strip()
            elif cur and line[:1].isdigit():
                parts = line.split()
                if len(parts) >= 2:
                    fn[cur] += int(parts[1])
        ranks.append(fn)
    return ranks


def kind(name):
    for k, rx in KINDS:
        if re.search(rx, name):
            return k
    return 'other'


def main():
    n, steps = float(sys.argv[1]), float(sys.argv[2])
    cols = []
    for arg in sys.argv[3:]:
        label, dirs = arg.split('=', 1)
        a, b = dirs.split(':')
        ra, rb = load(a), load(b)
        per_rank = []
        for fa, fb in zip(ra, rb):
            d = collections.Counter(fb)
            d.subtract(fa)
            per_rank.append(d)
        by = collections.Counter()
        for d in per_rank:
            for name, v in d.items():
                by[kind(name)] += v
        total = sum(by.values())
        slowest = max(sum(d.values()) for d in per_rank) * len(per_rank)
        # the same without the MPI library, whose polling while a rank waits follows the load
        slowest_work = max(sum(v for name, v in d.items() if kind(name) != KINDS[6][0])
                           for d in per_rank) * len(per_rank)
        cols.append((label, by, total, slowest, slowest_work))
    scale = 1.0 / (n * steps)
    print('| kind | ' + ' | '.join(c[0] for c in cols) + ' |')
    print('|---|' + '---|' * len(cols))
    for k in [k for k, _ in KINDS] + ['other']:
        print('| %s | ' % k + ' | '.join('%.0f' % (c[1][k] * scale) for c in cols) + ' |')
    print('| **total** | ' + ' | '.join('**%.0f**' % (c[2] * scale) for c in cols) + ' |')
    base = cols[0][2]
    print('| total / first column | ' + ' | '.join('%.3f' % (c[2] / base) for c in cols) + ' |')
    mpi = KINDS[6][0]
    print('| total without the MPI library / first column | ' +
          ' | '.join('%.3f' % ((c[2] - c[1][mpi]) / (base - cols[0][1][mpi])) for c in cols) + ' |')
    print('| slowest rank x K / first column | ' +
          ' | '.join('%.3f' % (c[3] / base) for c in cols) + ' |')
    print('| slowest rank x K without the MPI library / first column | ' +
          ' | '.join('%.3f' % (c[4] / (base - cols[0][1][mpi])) for c in cols) + ' |')


if __name__ == '__main__':
    main()
